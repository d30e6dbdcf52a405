"""`vega guidance`: the reference file, its summary and plot from the command line, and the
refusals of bad arguments (one line, exit 2, nothing written)."""

import json

import pytest

from cli_errors import assert_refused
from vega_cli import cli
from vega_gnc.guidance_reference import load_guidance_reference


@pytest.mark.slow
def test_writes_a_reference_the_flight_side_loads(tmp_path, capsys):
    out, plot = tmp_path / "ref.npz", tmp_path / "figs" / "ref.png"
    assert cli.main(["guidance", "--out", str(out), "--plot", str(plot),
                     "--wind-scale", "0.5"]) == 0
    text = capsys.readouterr().out
    assert f"wrote {out}" in text and "max |Qα|/envelope" in text
    ref = load_guidance_reference(out)
    assert ref.metadata["design_wind"]["scale"] == 0.5
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["summary"]["wind_max_mps"] == pytest.approx(7.0)    # 0.5 × 14 m/s
    assert plot.stat().st_size > 0 and not out.with_suffix(".png").exists()


@pytest.mark.parametrize("args, message", [
    (["--out", "{d}/ref.txt"], "must end in .npz"),
    (["--out", "{d}/ref.npz", "--plot", "{d}/p.jpg"], "must end in .png"),
    (["--out", "{d}/ref.npz", "--wind-scale", "5"], "--wind-scale must be within ±3"),
    (["--out", "{d}/ref.npz", "--wind-shift-m", "nan"], "must be finite"),
])
def test_bad_arguments(tmp_path, capsys, args, message):
    assert_refused(["guidance", *(a.replace("{d}", str(tmp_path)) for a in args)], capsys,
                   message)
    assert not any(tmp_path.iterdir())
