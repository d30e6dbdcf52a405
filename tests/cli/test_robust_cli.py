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
    # every worst-case rigid margin names its crossover: the worst plant's exact sampled-data
    # loop recomputed here gives the same frequencies, the PM is the distance from −180° at a
    # crossover at or above the frozen-time floor; the table prints them
    from vega_loops import margins as M
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_model.parameters import default_context

    context = default_context()
    ld = M.loop_data(load_controller_table(default_table_path()), context, 50.0)
    loop = M.frozen_loop(ld, *M.corner_plant(context, 50.0, row["worst_deviations"]))
    ref = M.extract_margins(ld.w_radps, loop.L_d, loop.omega_modes)
    for key in ("gm_low_db", "gm_high_db", "pm_deg"):
        w_key = M.FREQUENCY_OF[key]
        assert row[f"worst_{key}"] == pytest.approx(ref[key], rel=1e-9)
        assert row[f"worst_{w_key}"] == pytest.approx(ref[w_key], rel=1e-9)
        assert data["summary"][f"worst_{key}"]["w_radps"] == row[f"worst_{w_key}"]
        assert f"worst_{w_key}" in header and f"nominal_{w_key}" in header
    assert row["worst_pm_deg"] == pytest.approx(abs(row["worst_pm_signed_deg"]))
    assert row["worst_w_pm_radps"] >= M.PM_FLOOR_RADPS
    assert f"{row['worst_pm_deg']:.1f}@{row['worst_w_pm_radps']:<6.3g}" in out
    assert "PM (distance from -180 deg)" in out
    # the μ bound's whole-matrix ab13md calls, per row and in the summary and the table
    calls, won, stopped = (row[f"mu_whole_{k}"] for k in ("calls", "won", "stopped"))
    assert calls >= won >= 0 and calls >= stopped >= 0 and calls > 0
    assert row["mu_whole_time_s"] >= 0.0 and "mu_whole_calls" in header
    summary = data["summary"]
    assert (summary["mu_whole_calls"], summary["mu_whole_won"],
            summary["mu_whole_stopped"]) == (calls, won, stopped)
    assert summary["mu_whole_stopped_times_s"] == ([50.0] if stopped else [])
    assert f"mu whole-matrix ab13md calls: {calls} made, {won} gave the smaller" in out


@pytest.mark.slow
def test_no_mu_skips_the_upper_bound(tmp_path, capsys):
    code = cli.main(["robust", "--at", "90", "--no-mu", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    row = json.loads((tmp_path / "robust.json").read_text())["rows"][0]
    assert "mu_upper" not in row and "mu upper bound: not computed (--no-mu)" in out
    assert "mu_whole_calls" not in row and "whole-matrix" not in out
    assert not (tmp_path / "mu_max_q.png").exists()
