"""``vega linearize`` and ``vega plots model``: the views of the vehicle model."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from vega_model.dynamics import linear_model
from vega_model.parameters import model_parameters
from vega_cli import cli
from vega_cli.commands.linearize import parse_times

REPO = Path(__file__).resolve().parents[2]
REQUIRED_PARAMETERS = ("v_mps", "q_pa", "mach", "s_ref_m2", "cn_alpha_per_rad", "x_cp_m",
                       "x_cg_m", "x_pvp_m", "x_ins_m", "jyy_kgm2", "mass_kg", "thrust_n",
                       "f1_hz", "f2_hz", "zeta")


def test_linearize_json_single_time(capsys):
    assert cli.main(["linearize", "--t", "47", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["t_s"] == 47.0
    assert rec["states"][0] == "theta_rad" and rec["inputs"][2] == "wind_mps"
    assert rec["outputs"][0] == "q_alpha_pa_rad"
    A, B, C, D = linear_model(model_parameters(47.0))
    for name, m in (("A", A), ("B", B), ("C", C), ("D", D)):
        assert np.array_equal(np.array(rec[name]), m)
    for key in REQUIRED_PARAMETERS:
        assert isinstance(rec["parameters"][key], float), key
    assert rec["parameters"]["x_pvp_m"] == 0.96 and rec["parameters"]["x_ins_m"] == 22.9
    assert rec["parameters"]["f1_hz"] == pytest.approx(4.71 + 0.47 * 1.18)


@pytest.mark.slow
def test_linearize_range_through_the_installed_command():
    """The real `vega` wrapper (as users run it): one process, a JSON list of 9 models."""
    vega = REPO / ".venv" / "bin" / "vega"
    assert vega.exists(), "run `make setup` first (it installs .venv/bin/vega)"
    out = subprocess.run([str(vega), "linearize", "--t", "10:90:10", "--json"],
                         capture_output=True, text=True, timeout=120, check=True).stdout
    records = json.loads(out)
    assert [r["t_s"] for r in records] == [10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0]
    q = [r["parameters"]["q_pa"] for r in records]
    assert int(np.argmax(q)) == 4  # max-Q near 47 s: the 50 s point is the largest


@pytest.mark.parametrize("arg, message", [
    ("abc", "expected SECONDS or START:STOP:STEP"),
    ("10:5:1", "STOP >= START"),
    ("1:2", "expected SECONDS or START:STOP:STEP"),
    ("nan", "must be finite"),
])
def test_parse_times_rejects(arg, message):
    with pytest.raises(ValueError, match=message):
        parse_times(arg)


def test_linearize_outside_table_is_one_line_error(capsys):
    assert cli.main(["linearize", "--t", "500", "--json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vega: error: --t 500: outside the flight-condition table")
    assert err.count("\n") == 1


def test_range_parsing_includes_stop():
    times, is_range = parse_times("0:1:0.1")
    assert is_range and len(times) == 11 and times[-1] == 1.0


@pytest.mark.slow
def test_plots_model_writes_pngs(tmp_path, capsys):
    assert cli.main(["plots", "model", "--out", str(tmp_path)]) == 0
    for name in ("bode_theta_ins_beta.png", "pole_zero.png"):
        data = (tmp_path / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000
