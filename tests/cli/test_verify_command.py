"""``vega verify`` (vega_cli.signoff.verify): the sign-off checks of a controller table in one
command.

Bad input is refused in one line (exit 2) before anything runs; a real, short run (the dispersed
margins at one time, a two-flight campaign) reports the repository commands' own figures and
gates on them (a campaign passing fewer flights than the reference fails the sign-off); the
dispersed figures are read from a hand-made margins summary.
"""

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from vega_cli import cli
from vega_cli.signoff import record as R
from vega_cli.signoff import verify as V

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws/src/vega_gnc/config/tvc_controller.npz"


def _verify(args) -> int:
    return cli.main(["verify", *args])


@pytest.mark.parametrize("args, message", [
    (["{d}/missing.npz", "--out", "{d}/o"], "table {d}/missing.npz:"),
    ([str(SHIPPED), "--out", "{d}/o", "--workers", "0"], "--workers 0: must be within"),
    ([str(SHIPPED), "--out", "{d}/o", "--at", "43:40:1"], "--at"),
    ([str(SHIPPED), "--out", "{d}/o", "--checks", "sil,fly"], "--checks sil,fly: each of"),
    ([str(SHIPPED), "--out", "{d}/o", "--scenarios", "nominal,nope"], "--scenarios nope:"),
    ([str(SHIPPED), "--out", "{d}/o", "--runs", "0"], "--runs 0: must be within"),
    ([str(SHIPPED), "--out", "{d}/o", "--flight-day-runs", "0"],
     "--flight-day-runs 0: must be within"),
    ([str(SHIPPED), "--out", "{d}/full"], "--out {d}/full: exists and is not an empty"),
    ([str(SHIPPED), "--out", "{d}/o", "--heldout-reference", "{d}/full"],
     "--heldout-reference {d}/full: no campaign.json (not a `vega mc run` campaign)"),
])
def test_bad_input_is_one_line_and_exit_2_before_anything_runs(tmp_path, capsys, args,
                                                               message):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "kept.txt").write_text("x")
    code = _verify([a.replace("{d}", str(tmp_path)) for a in args])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("vega: error: ")
    assert message.replace("{d}", str(tmp_path)) in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full"]
    assert (tmp_path / "full" / "kept.txt").read_text() == "x"


def test_the_default_out_is_a_new_directory_per_run_under_bags():
    from datetime import datetime, timezone

    when = datetime(2026, 12, 2, 17, 15, 35, tzinfo=timezone.utc)
    assert V.default_out(when) == Path("bags/verify-20261202T171535Z")


def _summary(unstable=0, b1_fail=0, b2_fail=0):
    family = {"stability": {"n_unstable_loops": unstable},
              "bending_1": {"n_fail_times": b1_fail, "fail_intervals_s": [[43.0, 43.0]] * b1_fail},
              "bending_2": {"n_fail_times": b2_fail, "fail_intervals_s": []},
              "pm_deg": {"worst": 14.91, "t_s": 50.0, "corner": 567, "family": "bending",
                         "w_radps": 8.25},
              "pm_below_floor": {"floor_radps": 0.15, "n_loops": 21718, "worst": 30.7,
                                 "t_s": 46.0, "corner": 287, "w_radps": 0.020}}
    nominal = {k: {"worst": w, "t_s": 41.0, "corner": 0, "w_radps": wc} for k, w, wc in (
        ("gm_low_db", 6.06, 0.92), ("gm_high_db", 6.08, 5.1), ("pm_deg", 30.02, 1.83))}
    nominal.update({k: {"worst": w, "t_s": 41.0, "corner": 0, "w_peak_radps": wc}
                    for k, w, wc in (("bending_1", -10.6, 33.0), ("bending_2", -26.4, 90.0))})
    nominal["stability"] = {"n_unstable_loops": 0}
    nominal["pm_below_floor"] = {"floor_radps": 0.15, "n_loops": 0, "worst": None}
    return {"dispersed": {"families": {"all": {"requirements": family}}}, "nominal": nominal}


def test_dispersed_figures_from_a_hand_summary():
    f = V.dispersed_figures(_summary(unstable=2, b1_fail=1, b2_fail=0))
    assert f["unstable_loops"] == 2 and f["bending_miss_times"] == 1
    assert f["bending_miss_intervals_s"]["bending_1"] == [[43.0, 43.0]]
    assert f["nominal_worst"]["pm_deg"] == [30.02, 41.0]
    assert V.dispersed_figures(_summary(b2_fail=3))["bending_miss_times"] == 3
    # reported with each worst margin: its crossover (a bending band: its peak), the dispersed
    # worst PM (distance) with corner, time and frequency, the crossovers below the floor
    assert f["nominal_worst_w_radps"] == {"gm_low_db": 0.92, "gm_high_db": 5.1, "pm_deg": 1.83,
                                          "bending_1": 33.0, "bending_2": 90.0}
    assert f["dispersed_worst"]["pm_deg"] == {"value": 14.91, "t_s": 50.0, "corner": 567,
                                              "w_radps": 8.25}
    assert f["dispersed_worst"]["gm_low_db"] is None          # not in the hand summary
    assert f["pm_below_floor"]["dispersed"] == {"floor_radps": 0.15, "n_loops": 21718,
                                                "value": 30.7, "t_s": 46.0, "corner": 287,
                                                "w_radps": 0.020}
    assert f["pm_below_floor"]["nominal"] == {"floor_radps": 0.15, "n_loops": 0, "value": None}


def test_campaign_failures_counted_per_requirement_from_a_hand_summary():
    """A failed sample names its requirements comma-separated (campaign_run's summary.json):
    each counts once per requirement, not per character."""
    summary = {"runs": 10, "passed": 6, "unstable": 0, "pass_fraction_lower_90": 0.4,
               "failed_samples": [{"sample": 1, "failed": "q_alpha"},
                                  {"sample": 4, "failed": "q_alpha,drift_rate"},
                                  {"sample": 7, "failed": "drift"},
                                  {"sample": 9, "failed": "q_alpha"}]}
    f = V.mc_figures(summary, 746)
    assert f["failures_by_requirement"] == {"q_alpha": 3, "drift_rate": 1, "drift": 1}
    assert (f["runs"], f["passed"], f["unstable"], f["reference_passed"]) == (10, 6, 0, 746)


def _flight_day_summary(n=1440, passed=1440, unstable=0, rate=0, design=(1.0, 0.95),
                        availability=(0.7, 0.95)):
    from vega_campaign.campaign_run import clopper_pearson_lower

    lo = clopper_pearson_lower(passed, n, 0.90)
    return {"flight_day": {"n": n, "passed": passed, "failed": n - passed, "scrubbed": 7,
                           "lower_bound_90": lo, "demonstrated_99_73_at_90": lo >= 0.9973,
                           "unstable": unstable, "rate_limited": rate,
                           "scrub_reasons": {"ground_wind": 7}},
            "availability": {"1": availability[0], "2": availability[1]},
            "availability_design": {"1": design[0], "2": design[1]},
            "max_abs_q_alpha_pa_deg": {"go_max": 1.5e5, "all_max": 1.6e5}}


@pytest.mark.parametrize("change, gate", [
    ({}, True),                                          # availability 0.7 is reported only
    ({"n": 1440, "passed": 1439}, True),                 # one failure in 1 440: 0.99730…
    ({"n": 1440, "passed": 1438}, False),
    ({"n": 851, "passed": 851}, False),                  # 852 needed without a failure
    ({"n": 852, "passed": 852}, True),
    ({"unstable": 1}, False), ({"rate": 1}, False),
    ({"design": (0.9, 1.0)}, True), ({"design": (0.8999, 1.0)}, False),
])
def test_flight_day_gate_on_hand_summaries(change, gate):
    f = V.flight_day_figures(_flight_day_summary(**change))
    assert V.flight_day_passed(f) is gate
    assert f["availability_min"] == min(_flight_day_summary(**change)["availability"].values())


@pytest.mark.slow
def test_a_short_flight_day_check_records_and_gates(tmp_path, capsys):
    """Two flight-day samples cannot show 99.73 % at 90 %: the check runs the real campaign,
    records its figures and fails the gate."""
    out = tmp_path / "v"
    code = _verify([str(SHIPPED), "--out", str(out), "--checks", "flight-day",
                    "--flight-day-runs", "2", "--workers", "1"])
    report = json.loads((out / "verify.json").read_text())
    assert code == 1 and report["signed_off"] is False
    (check,) = report["checks"]
    f = check["figures"]
    assert check["check"] == "flight-day 2 samples" and check["gated"] and not check["passed"]
    assert f["n"] + f["scrubbed"] == 2 and not f["demonstrated_99_73_at_90"]
    assert set(f["availability"]) == {"1", "2"} and set(f["availability_design"]) == {"1", "2"}
    assert (out / "flight_day" / "summary.json").exists()
    assert "flight-day 2 samples: FAIL" in capsys.readouterr().out


@pytest.mark.slow
def test_a_short_real_sign_off_reports_and_gates(tmp_path, capsys):
    """Margins at max-Q (43 s) with every dispersed corner, then a two-flight campaign against a
    reference of three passes: the margins pass, the campaign cannot reach its reference, so
    the sign-off fails (exit 1) with every figure recorded."""
    out = tmp_path / "v"
    code = _verify([str(SHIPPED), "--out", str(out), "--checks", "margins,mc", "--at", "43",
                   "--runs", "2", "--mc-reference", "3", "--workers", "1"])
    report = json.loads((out / "verify.json").read_text())
    assert code == 1 and report["signed_off"] is False
    # the record names the bytes it verified and how far it went (vega ship reads both)
    assert report["table_sha256"] == hashlib.sha256(SHIPPED.read_bytes()).hexdigest()
    assert report["scope"] == {"checks": ["margins", "mc"],
                               "scenarios": list(R.GATED_SCENARIOS + R.REPORTED_SCENARIOS),
                               "at": "43", "runs": 2, "mc_reference": 3,
                               "flight_day_runs": 1440}
    margins, mc = report["checks"]
    assert margins["check"] == "margins --dispersed" and margins["exit"] == 0
    assert margins["passed"] and margins["figures"]["unstable_loops"] == 0
    assert margins["figures"]["bending_miss_times"] == 0
    gm_low, t = margins["figures"]["nominal_worst"]["gm_low_db"]
    assert t == 43.0 and 6.0 <= gm_low < 8.0           # the shipped table at max-Q: 6.30 dB
    # reported, not gated: the crossover of each worst margin, the nominal ones as the nominal
    # loop at 43 s recomputed gives them; the dispersed worst PM (a distance) with its corner
    from vega_gnc.controller_table import load_controller_table
    from vega_loops import margins as M
    from vega_model.parameters import default_context

    ref = M.analyse_time(load_controller_table(SHIPPED), default_context(), 43.0, [(0, {})],
                         nyquist=False)[0]
    w = margins["figures"]["nominal_worst_w_radps"]
    for key in ("gm_low_db", "gm_high_db", "pm_deg"):
        assert w[key] == pytest.approx(ref[M.FREQUENCY_OF[key]], rel=1e-9)
    pm = margins["figures"]["dispersed_worst"]["pm_deg"]
    assert pm["t_s"] == 43.0 and 0 <= pm["corner"] and 0.0 < pm["value"] <= 180.0
    assert pm["w_radps"] >= M.PM_FLOOR_RADPS
    assert margins["figures"]["pm_below_floor"]["dispersed"]["floor_radps"] == M.PM_FLOOR_RADPS
    assert mc["figures"]["runs"] == 2 and mc["figures"]["unstable"] == 0
    assert mc["figures"]["reference_passed"] == 3 and not mc["passed"]
    assert (out / "mc" / "summary.json").exists() and (out / "margins.log").exists()
    printed = capsys.readouterr().out
    assert "mc 2 flights: FAIL" in printed and "a gated check FAILED" in printed


def test_a_table_changed_while_the_checks_run_is_not_signed_off(tmp_path, monkeypatch, capsys):
    """The SHA-256 is taken when the table is read; a file changed before the record is written
    (here by the SIL check itself, the one check stood in for) is no sign-off of any bytes,
    even with every gated check passed."""
    table = tmp_path / "t.npz"
    shutil.copyfile(SHIPPED, table)
    read = hashlib.sha256(table.read_bytes()).hexdigest()

    def sil_that_edits_the_table(path, out, scenarios):
        with open(path, "ab") as f:
            f.write(b"\0")
        return [{"check": "sil nominal", "exit": 0, "wall_s": 0.0, "gated": True,
                 "passed": True, "figures": {}}]

    monkeypatch.setattr(V, "check_sil", sil_that_edits_the_table)
    out = tmp_path / "v"
    assert _verify([str(table), "--out", str(out), "--checks", "sil",
                    "--scenarios", "nominal"]) == 1
    report = json.loads((out / "verify.json").read_text())
    assert report["signed_off"] is False and report["table_sha256"] == read
    assert report["checks"][0]["passed"]
    assert "changed while the checks ran: not signed off" in capsys.readouterr().out


@pytest.mark.slow
def test_a_held_out_seed_is_flown_on_the_reference_samples_and_reported(tmp_path, capsys):
    """A two-flight campaign of the shipped table on seed 5 is the held-out reference; the
    verification flies the table on its samples and compares them flight by flight: the same
    table, so nothing lost or won. Reported, never gated, and outside the checks' scope."""
    ref = tmp_path / "ref"
    assert cli.main(["mc", "run", "--environment", "thesis-box", "--runs", "2", "--seed", "5",
                     "--workers", "1", "--table", str(SHIPPED), "--out", str(ref)]) in (0, 1)
    flown = json.loads((ref / "summary.json").read_text())
    out = tmp_path / "v"
    code = _verify([str(SHIPPED), "--out", str(out), "--checks", "mc", "--runs", "2",
                    "--workers", "1", "--heldout-reference", str(ref)])
    report = json.loads((out / "verify.json").read_text())
    mc, held = report["checks"]
    assert code == (0 if mc["passed"] else 1) and report["signed_off"] is (code == 0)
    assert report["scope"]["checks"] == ["mc"]
    assert report["scope"]["heldout_reference"] == str(ref)
    assert held["check"] == "mc held-out seed 5" and held["gated"] is False
    f = held["figures"]
    assert (f["seed"], f["runs"], f["lost"], f["won"]) == (5, 2, [], [])
    assert f["reference_passed"] == f["passed"] == flown["passed"] and held["passed"]
    assert (out / "mc_heldout_compare.png").stat().st_size > 10_000
    assert "mc held-out seed 5: reported: pass" in capsys.readouterr().out
