"""`vega robust`: refusals of bad arguments (one line, exit 2, nothing written) and one frozen
time end to end (worst case, disk margins, files); the methods are tested in
tests/synthesis/test_robust.py."""

import json
from pathlib import Path

import pytest

from cli_errors import assert_refused
from vega_cli import cli


@pytest.mark.parametrize("args, message", [
    (["--at", "150"], "--at 150: outside the flight-condition table"),
    (["--workers", "0"], "--workers 0: must be within 1..64"),
    (["--seed", "-1"], "--seed -1: must be within 0..2**32-1"),
    (["--table", "{d}/missing.npz"], "missing.npz"),
    (["--at", "x"], "--at"),
])
def test_bad_arguments(tmp_path, capsys, args, message):
    out = tmp_path / "out"
    assert_refused(["robust", "--out", str(out),
                    *(a.replace("{d}", str(tmp_path)) for a in args)], capsys, message)
    assert not out.exists()


@pytest.mark.slow
def test_one_time_end_to_end(tmp_path, capsys):
    code = cli.main(["robust", "--at", "50", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "no unstable plant found" in out and "bending criteria at the worst case: met" in out
    data = json.loads((tmp_path / "robust.json").read_text())
    row = data["rows"][0]
    assert row["t_s"] == 50.0 and row["worst_n_unstable"] == 0
    # the worst case is worse than the nominal plant, and the lower bound comes from a
    # destabilising scale beyond the set (the set itself is stable)
    assert 0.0 < row["worst_disk_alpha"] < row["nominal_disk_alpha"]
    assert row["s_star"] > 1.0 and row["mu_lower"] == pytest.approx(1.0 / row["s_star"])
    header = (tmp_path / "robust.csv").read_text().splitlines()[0].split(",")
    assert "worst_disk_alpha" in header and "dev_bending_frequency_1" in header
    assert Path(tmp_path / "robust_over_time.png").stat().st_size > 10_000
    # the μ upper bound: above the lower bound of the same time (μ_low ≤ μ ≤ μ_up), from a
    # stable centre, its curve plotted; the summary states it
    assert row["mu_centre_stable"] and row["mu_fallbacks"] == 0
    assert row["mu_lower"] <= row["mu_upper"] < 10.0
    assert max(row["mu_curve"]["mu_upper"]) == pytest.approx(row["mu_upper"])
    assert data["summary"]["mu_upper"]["value"] == row["mu_upper"]
    assert f"mu upper bound peak {row['mu_upper']:.3f} at 50 s" in out
    assert "mu_curve" not in header
    assert Path(tmp_path / "mu_max_q.png").stat().st_size > 10_000


@pytest.mark.slow
def test_no_mu_skips_the_upper_bound(tmp_path, capsys):
    code = cli.main(["robust", "--at", "90", "--no-mu", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    row = json.loads((tmp_path / "robust.json").read_text())["rows"][0]
    assert "mu_upper" not in row and "mu upper bound: not computed (--no-mu)" in out
    assert not (tmp_path / "mu_max_q.png").exists()
