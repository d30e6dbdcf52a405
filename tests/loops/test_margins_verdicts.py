"""``vega_loops.margins``: the verdicts, summaries and output helpers, against values
worked out by hand in the test.

The rows are hand-made dicts with the keys :func:`analyse_time` writes; every expected number
below is read off those rows by hand (which row is worst, which times fail, which intervals
they form), never by calling the function the code under test calls. Each requirement is
checked exactly at its threshold (passes: "≥ 6 dB", "≤ −6 dB") and just beyond it (fails),
on both sides.
"""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from vega_loops import margins as M

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "lpv_controller.npz"
INF = math.inf
NAN = math.nan


def _row(t, corner=0, **kw):
    """A row that passes everything (values unique per row: they tell which row was picked)."""
    r = {"t_s": float(t), "corner": corner, "v_sched_mps": 100.0 + t, "clamped": False,
         "gm_low_db": 20.0 + t, "w_gm_low_radps": 0.1 + t, "gm_high_db": 21.0 + t,
         "w_gm_high_radps": 5.0 + t, "pm_deg": 50.0 + t, "w_pm_radps": 2.0 + t,
         "pm_signed_deg": 50.0 + t, "n_gain_crossovers": 1, "pm_low_deg": INF,
         "w_pm_low_radps": NAN, "n_low_gain_crossovers": 0,
         "b1_peak_db": -20.0 - t, "b1_w_peak_radps": 30.0 + t, "b1_pm_deg": INF,
         "b1_w_pm_radps": NAN, "b1_gm_db": INF, "b1_w_gm_radps": NAN,
         "b1_phase_stabilised": False,
         "b2_peak_db": -25.0 - t, "b2_w_peak_radps": 70.0 + t, "b2_pm_deg": INF,
         "b2_w_pm_radps": NAN, "b2_gm_db": INF, "b2_w_gm_radps": NAN,
         "b2_phase_stabilised": False, "hf_peak_db": -30.0,
         "n_unstable": 0, "max_abs_eig": 0.99, "n_open_unstable": 0, "n_unstable_nyquist": 0,
         "sd_gm_low_db": 20.0 + t, "sd_w_gm_low_radps": 0.1 + t, "sd_gm_high_db": 21.0 + t,
         "sd_w_gm_high_radps": 5.0 + t, "sd_pm_deg": 50.0 + t, "sd_w_pm_radps": 2.0 + t,
         "sd_b1_peak_db": -20.0 - t, "sd_b2_peak_db": -25.0 - t}
    r.update(kw)
    return r


def _bending(peak, pm, gm):
    return {"b1_peak_db": peak, "b1_pm_deg": pm, "b1_gm_db": gm,
            "b1_w_pm_radps": 31.0 - peak, "b1_w_gm_radps": 34.0 - peak,
            "b1_phase_stabilised": peak > -6.0}


# ------------------------------------------------------------------------ single criteria
@pytest.mark.parametrize("peak, pm, gm, ok", [
    (-6.0, 0.0, 0.0, True),            # exactly −6 dB: gain-stabilised (≤)
    (-6.001, 0.0, 0.0, True),
    (-5.999, 30.0, 6.0, True),         # above −6 dB: both band margins exactly at the limit
    (-5.999, 29.999, 6.0, False),
    (-5.999, 30.0, 5.999, False),
    (-5.999, 29.0, 5.0, False),
    (3.0, INF, INF, True),             # phase-stabilised, no crossover in the band
    (3.0, 45.0, 12.0, True),
])
def test_bending_ok_at_the_thresholds(peak, pm, gm, ok):
    row = {"b2_peak_db": peak, "b2_pm_deg": pm, "b2_gm_db": gm,
           "b1_peak_db": -50.0, "b1_pm_deg": 0.0, "b1_gm_db": 0.0}
    assert M.bending_ok(row, 2) is ok
    assert M.bending_ok(row, 1) is True          # the other mode's keys are not read


@pytest.mark.parametrize("peak, pm, gm, ok", [
    (-3.0, 0.0, 0.0, True), (-2.999, 20.0, 3.0, True), (-2.999, 19.999, 3.0, False),
    (-2.999, 20.0, 2.999, False), (-4.5, 0.0, 0.0, True)])
def test_bending_ok_with_the_dispersed_criterion(peak, pm, gm, ok):
    row = {"b1_peak_db": peak, "b1_pm_deg": pm, "b1_gm_db": gm}
    assert M.bending_ok(row, 1, M.DISPERSED_CRITERION) is ok
    # the same row against the nominal 6 dB / 30° criterion: everything above −6 dB fails
    assert M.bending_ok(row, 1) is (peak <= -6.0)


@pytest.mark.parametrize("key, value, ok", [
    ("gm_low_db", 6.0, True), ("gm_low_db", 5.999, False), ("gm_low_db", -7.0, False),
    ("gm_high_db", 6.0, True), ("gm_high_db", 5.999, False), ("gm_high_db", INF, True),
    ("pm_deg", 30.0, True), ("pm_deg", 29.999, False), ("pm_deg", -40.0, False),
])
def test_criteria_ok_each_rigid_criterion_at_its_threshold(key, value, ok):
    got = M.criteria_ok(_row(1.0, **{key: value}))
    assert got == {"gm_low_db": True, "gm_high_db": True, "pm_deg": True, "bending_1": True,
                   "bending_2": True, "stable": True, key: ok}


def test_criteria_ok_bending_modes_and_stability_are_told_apart():
    row = _row(2.0, **_bending(-1.0, 10.0, 10.0))          # mode 1 fails, mode 2 passes
    assert M.criteria_ok(row) == {"gm_low_db": True, "gm_high_db": True, "pm_deg": True,
                                  "bending_1": False, "bending_2": True, "stable": True}
    row = _row(2.0, b2_peak_db=-1.0, b2_pm_deg=10.0, b2_gm_db=10.0, n_unstable=1)
    assert M.criteria_ok(row) == {"gm_low_db": True, "gm_high_db": True, "pm_deg": True,
                                  "bending_1": True, "bending_2": False, "stable": False}


def test_criteria_ok_uses_the_given_requirements():
    row = _row(1.0, gm_low_db=4.0, gm_high_db=3.0, pm_deg=20.0,
               **_bending(-4.0, 25.0, 4.0))
    assert M.criteria_ok(row) == {"gm_low_db": False, "gm_high_db": False, "pm_deg": False,
                                  "bending_1": False, "bending_2": True, "stable": True}
    assert all(M.criteria_ok(row, M.DISPERSED_CRITERION).values())
    row = _row(1.0, gm_low_db=2.999, gm_high_db=2.999, pm_deg=19.999,
               **_bending(-2.0, 19.0, 4.0))
    assert M.criteria_ok(row, M.DISPERSED_CRITERION) == {
        "gm_low_db": False, "gm_high_db": False, "pm_deg": False, "bending_1": False,
        "bending_2": True, "stable": True}


def test_worst_row_min_and_max():
    rows = [{"x": 3.0, "id": "a"}, {"x": -1.0, "id": "b"}, {"x": 7.0, "id": "c"},
            {"x": -1.0, "id": "d"}, {"x": 2.0, "id": "e"}]
    assert M.worst_row(rows, "x", "min")["id"] == "b"        # first of the tied minima
    assert M.worst_row(rows, "x", "max")["id"] == "c"
    assert M.worst_row(rows, "x", "min") is rows[1]
    assert M.worst_row([{"x": INF, "id": 0}, {"x": 4.0, "id": 1}], "x", "max")["id"] == 0
    assert M.worst_row([{"x": INF, "id": 0}, {"x": 4.0, "id": 1}], "x", "min")["id"] == 1
    assert M.worst_row([{"x": 1.0, "id": 0}], "x", "max")["id"] == 0


@pytest.mark.parametrize("selected, all_times, expected", [
    ([0.5, 1.0, 2.5], [0.0, 0.5, 1.0, 1.5, 2.0, 2.5], [[0.5, 1.0], [2.5, 2.5]]),
    ([0.0], [0.0, 1.0], [[0.0, 0.0]]),
    ([0.0, 1.0, 2.0], [2.0, 0.0, 1.0], [[0.0, 2.0]]),            # all_times unsorted
    ([3.0, 1.0], [0.0, 1.0, 2.0, 3.0], [[1.0, 1.0], [3.0, 3.0]]),
    ([], [0.0, 1.0], []),
    ([1.0, 2.0, 4.0, 5.0, 6.0], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], [[1.0, 2.0], [4.0, 6.0]]),
])
def test_intervals_by_hand(selected, all_times, expected):
    assert M._intervals(selected, all_times) == expected


# ---------------------------------------------------------------------- the rows of a sweep
def _sweep_rows():
    """Two corners at t = 0 … 4 (hand-picked margins; comments: what fails)."""
    return [
        _row(0, 0),
        _row(0, 1, gm_low_db=5.0, w_gm_low_radps=0.7,                 # gm_low fails (5 < 6)
             **_bending(-3.0, 40.0, 8.0),                             # mode 1 phase-stab., ok
             pm_low_deg=48.0, w_pm_low_radps=0.03, n_low_gain_crossovers=1),  # drift: info
        _row(1, 0, gm_high_db=6.0, w_gm_high_radps=9.5, pm_deg=30.0,  # both exactly at limits
             b2_peak_db=-5.0, b2_pm_deg=25.0, b2_gm_db=10.0,           # mode 2 fails (25°)
             b2_phase_stabilised=True, b2_w_peak_radps=71.5, b2_w_pm_radps=72.0,
             b2_w_gm_radps=69.0),
        _row(1, 1, n_unstable=2, gm_low_db=0.1, pm_deg=0.5, b1_peak_db=30.0,  # unstable
             b2_peak_db=30.0, b2_pm_deg=0.0, b2_gm_db=0.0, pm_low_deg=1.0,
             w_pm_low_radps=0.01, n_low_gain_crossovers=2),
        _row(2, 0, pm_deg=29.0, w_pm_radps=3.3,                       # pm fails
             pm_low_deg=33.0, w_pm_low_radps=0.025, n_low_gain_crossovers=1),  # drift: info
        _row(2, 1, gm_low_db=5.5, gm_high_db=5.0, **_bending(-2.0, 35.0, 7.0)),
        _row(3, 0),
        _row(3, 1, n_unstable=1),
    ]


def test_worst_per_time_by_hand():
    rows = _sweep_rows() + [_row(4, 0, n_unstable=1), _row(4, 1, n_unstable=3,
                                                            **_bending(2.0, 1.0, 1.0))]
    got = M.worst_per_time(rows)
    assert [r["t_s"] for r in got] == [0.0, 1.0, 2.0, 3.0, 4.0]
    t0, t1, t2, t3, t4 = got
    # below the floor (informational): corner 1's drift crossover, with its frequency
    low = {k: t0.pop(k) for k in ("pm_low_deg", "pm_low_deg_corner", "pm_low_deg_freq_radps")}
    assert low == {"pm_low_deg": 48.0, "pm_low_deg_corner": 1, "pm_low_deg_freq_radps": 0.03}
    # each worst value with the frequency of the worst row's crossover (row values by hand)
    assert t0 == {"t_s": 0.0, "n_plants": 2, "n_unstable_plants": 0,
                  "gm_low_db": 5.0, "gm_low_db_corner": 1, "gm_low_db_freq_radps": 0.7,
                  "gm_high_db": 21.0, "gm_high_db_corner": 0, "gm_high_db_freq_radps": 5.0,
                  "pm_deg": 50.0, "pm_deg_corner": 0, "pm_deg_freq_radps": 2.0,
                  "b1_peak_db": -3.0, "b1_peak_db_corner": 1, "b1_peak_db_freq_radps": 30.0,
                  "b2_peak_db": -25.0, "b2_peak_db_corner": 0, "b2_peak_db_freq_radps": 70.0,
                  "bending_1_fail_plants": 0, "bending_2_fail_plants": 0}
    # t = 1: the unstable corner 1 is not the worst of anything, but is counted
    assert t1["n_unstable_plants"] == 1 and t1["n_plants"] == 2
    assert (t1["gm_low_db"], t1["gm_low_db_corner"]) == (21.0, 0)
    assert (t1["pm_deg"], t1["b1_peak_db"], t1["b2_peak_db"]) == (30.0, -21.0, -5.0)
    # every plant's bending verdict counts, the unstable one's too (30 dB, no band margins)
    assert (t1["bending_1_fail_plants"], t1["bending_2_fail_plants"]) == (0, 2)
    assert (t2["gm_low_db"], t2["gm_low_db_corner"]) == (5.5, 1)
    assert (t2["gm_high_db"], t2["gm_high_db_corner"]) == (5.0, 1)
    assert (t2["pm_deg"], t2["pm_deg_corner"], t2["pm_deg_freq_radps"]) == (29.0, 0, 3.3)
    assert (t2["b1_peak_db"], t2["b1_peak_db_corner"]) == (-2.0, 1)
    assert t3["n_unstable_plants"] == 1 and t3["gm_low_db_corner"] == 0
    # all unstable: no worst value, every plant counted
    assert t4["n_unstable_plants"] == 2 and t4["n_plants"] == 2
    for key in ("gm_low_db", "gm_high_db", "pm_deg", "b1_peak_db", "b2_peak_db"):
        assert math.isnan(t4[key]) and t4[f"{key}_corner"] is None
        assert math.isnan(t4[f"{key}_freq_radps"])
    assert (t4["bending_1_fail_plants"], t4["bending_2_fail_plants"]) == (1, 0)


def test_verdicts_by_hand():
    rows = _sweep_rows()
    corners = [{"a": 0.0, "b": 0.0}, {"a": 0.1, "b": 0.0}]
    v = M.verdicts(rows, corners)
    assert set(v) == {"gm_low_db", "gm_high_db", "pm_deg", "bending_1", "bending_2",
                      "pm_below_floor", "stability"}
    # below the floor: two stable loops (the unstable one's 1° does not count), no verdict
    assert v["pm_below_floor"] == {"floor_radps": M.PM_FLOOR_RADPS, "unit": "deg",
                                   "n_loops": 2, "worst": 33.0, "w_radps": 0.025, "t_s": 2.0,
                                   "corner": 0, "family": "nominal", "deviations": {}}
    assert v["gm_low_db"] == {"worst": 5.0, "unit": "dB", "pass": False, "n_fail_times": 2,
                              "fail_intervals_s": [[0.0, 0.0], [2.0, 2.0]], "t_s": 0.0,
                              "corner": 1, "family": "rigid", "deviations": {"a": 0.1},
                              "w_radps": 0.7}
    assert v["gm_high_db"] == {"worst": 5.0, "unit": "dB", "pass": False, "n_fail_times": 1,
                               "fail_intervals_s": [[2.0, 2.0]], "t_s": 2.0, "corner": 1,
                               "family": "rigid", "deviations": {"a": 0.1},
                               "w_radps": 7.0}
    assert v["pm_deg"] == {"worst": 29.0, "unit": "deg", "pass": False, "n_fail_times": 1,
                           "fail_intervals_s": [[2.0, 2.0]], "t_s": 2.0, "corner": 0,
                           "family": "nominal", "deviations": {}, "w_radps": 3.3}
    # mode 1: worst peak −2 dB at t = 2 (corner 1), above −6 dB in two loops, all passing
    assert v["bending_1"] == {
        "worst": -2.0, "unit": "dB", "pass": True, "n_fail_times": 0, "fail_intervals_s": [],
        "t_s": 2.0, "corner": 1, "family": "rigid", "deviations": {"a": 0.1},
        "phase_stabilised": True, "pm_deg": 35.0, "gm_db": 7.0, "w_peak_radps": 32.0,
        "n_above_limit_loops": 2,
        "worst_band_pm": {"value": 35.0, "w_radps": 33.0, "t_s": 2.0, "corner": 1,
                          "family": "rigid", "deviations": {"a": 0.1}},
        "worst_band_gm": {"value": 7.0, "w_radps": 36.0, "t_s": 2.0, "corner": 1,
                          "family": "rigid", "deviations": {"a": 0.1}}}
    assert v["bending_2"] == {
        "worst": -5.0, "unit": "dB", "pass": False, "n_fail_times": 1,
        "fail_intervals_s": [[1.0, 1.0]], "t_s": 1.0, "corner": 0, "family": "nominal",
        "deviations": {}, "phase_stabilised": True, "pm_deg": 25.0, "gm_db": 10.0,
        "w_peak_radps": 71.5, "n_above_limit_loops": 1,
        "worst_band_pm": {"value": 25.0, "w_radps": 72.0, "t_s": 1.0, "corner": 0,
                          "family": "nominal", "deviations": {}},
        "worst_band_gm": {"value": 10.0, "w_radps": 69.0, "t_s": 1.0, "corner": 0,
                          "family": "nominal", "deviations": {}}}
    assert v["stability"] == {"n_unstable_loops": 2, "n_loops": 8, "n_unstable_times": 2,
                              "unstable_intervals_s": [[1.0, 1.0], [3.0, 3.0]], "pass": False}


def test_verdicts_relaxed_criterion_without_corners_and_all_passing():
    rows = _sweep_rows()
    v = M.verdicts(rows, None, M.DISPERSED_CRITERION)
    # 3 dB / 20°: everything stable passes; one corner only → no family/deviations
    for name in ("gm_low_db", "gm_high_db", "pm_deg", "bending_1", "bending_2"):
        assert v[name]["pass"] is True and v[name]["n_fail_times"] == 0
        assert v[name]["fail_intervals_s"] == []
        assert "family" not in v[name] and "deviations" not in v[name]
    assert v["gm_low_db"]["worst"] == 5.0 and v["gm_low_db"]["corner"] == 1
    stable = [r for r in rows if r["n_unstable"] == 0]
    good = M.verdicts(stable, [{"a": 0.0}])       # a single corner: no family either
    assert good["stability"] == {"n_unstable_loops": 0, "n_loops": 6, "n_unstable_times": 0,
                                 "unstable_intervals_s": [], "pass": True}
    assert "family" not in good["pm_deg"]
    # no loop above −6 dB: no band-margin entries
    quiet = M.verdicts([_row(0), _row(1)])
    assert quiet["bending_1"]["n_above_limit_loops"] == 0
    assert "worst_band_pm" not in quiet["bending_1"] and "worst_band_gm" not in quiet["bending_1"]
    assert quiet["bending_1"]["worst"] == -20.0 and quiet["bending_1"]["t_s"] == 0.0
    assert quiet["bending_1"]["pm_deg"] is None           # inf → null (strict JSON)
    assert quiet["gm_low_db"]["worst"] == 20.0 and quiet["gm_low_db"]["pass"] is True


def test_verdicts_all_unstable():
    rows = [_row(0, n_unstable=1), _row(0.5, n_unstable=2, gm_low_db=1.0)]
    v = M.verdicts(rows)
    for name in ("gm_low_db", "gm_high_db", "pm_deg", "bending_1", "bending_2"):
        assert v[name] == {"worst": None, "unit": v[name]["unit"], "pass": True,
                           "n_fail_times": 0, "fail_intervals_s": []}
    assert v["stability"] == {"n_unstable_loops": 2, "n_loops": 2, "n_unstable_times": 2,
                              "unstable_intervals_s": [[0.0, 0.5]], "pass": False}


# ------------------------------------------------------------------------------- summarise
def test_summarise_nominal_by_hand():
    from vega_gnc.controller_table import load_controller_table

    table = load_controller_table(SHIPPED)
    rows = [
        _row(0, clamped=True, v_sched_mps=95.0, pm_deg=28.0),      # clamped, pm fails
        _row(1, clamped=True, v_sched_mps=95.0, n_unstable=1, n_unstable_nyquist=1),
        _row(2, sd_gm_low_db=22.5, sd_pm_deg=51.0, n_unstable_nyquist=1),  # disagrees
        _row(3, sd_b1_peak_db=-22.0),
        _row(4, sd_gm_low_db=24.75, n_unstable=0),
        _row(5, clamped=True, v_sched_mps=1780.0, n_unstable=2,     # a clamped segment,
             n_unstable_nyquist=2),                                 # all unstable
    ]
    del rows[4]["n_unstable_nyquist"]        # absent off corner 0: compared with n_unstable
    for r in rows:                           # no finite sampled-data gm_high anywhere: 0
        r["sd_gm_high_db"] = INF
    result = {"rows": rows, "corners": [{"x": 0.0}], "run_time_s": 12.5, "workers": 2}
    s = M.summarise(result, table)
    assert s["what"] == ("classical margins of the flown (discrete, interpolated, clamped) "
                         "controller at the actuator input, per frozen flight time "
                         "(offline/vega_loops/margins.py)")
    assert s["loop"] == {
        "zoh": "exact fundamental (1 - exp(-jwT))/(jwT): phase = half-sample delay, "
               "magnitude sinc",
        "delay": "exact exp(-jw tau), tau = 39 ms nominal",
        "stability": "eigenvalues of the exact sampled-data closed loop (modified "
                     "z-transform), Nyquist cross-check on the nominal plant",
        "rigid_band": "w < 0.8 w1", "bending_band": "(0.8, 1.2) w_i",
        "phase_margin": "distance of the phase from -180 deg (mod 360, either side) at a "
                        "gain crossover; pm_deg over the rigid band at or above "
                        "pm_floor_radps, the crossovers below it reported apart",
        "pm_floor_radps": M.PM_FLOOR_RADPS}
    assert s["requirements"] == {"gm_db": 6.0, "pm_deg": 30.0, "bending_db": -6.0,
                                 "bending_phase_pm_deg": 30.0, "bending_phase_gm_db": 6.0}
    assert s["times_s"] == {"first": 0.0, "last": 5.0, "n": 6}
    assert (s["run_time_s"], s["workers"]) == (12.5, 2)
    assert s["table"] == {"path": str(SHIPPED), "git_revision":
                          table.metadata.get("git_revision"),
                          "grid_v_mps": [pytest.approx(95.6081449), pytest.approx(1780.22161)],
                          "rate_slice_mps2": pytest.approx(35.82683), "dt_s": 0.02}
    nom = s["nominal"]
    assert nom["pm_deg"]["fail_intervals_s"] == [[0.0, 0.0]]
    assert nom["stability"]["unstable_intervals_s"] == [[1.0, 1.0], [5.0, 5.0]]
    assert nom["clamped_intervals_s"] == [[0.0, 1.0], [5.0, 5.0]]
    assert nom["nyquist_disagreements"] == 1
    # |sd − continuous| over the rows where both are finite (pm: t = 0, |50 − 28|); 0 where
    # no row has both finite (gm_high) or none differs (b2)
    assert nom["sampled_data_vs_continuous_max_diff"] == {
        "gm_low_db": 0.75, "gm_high_db": 0.0, "pm_deg": 22.0, "b1_peak_db": 1.0,
        "b2_peak_db": 0.0}
    seg0, seg1 = nom["clamped_segments"]
    assert seg0["interval_s"] == [0.0, 1.0] and seg0["v_sched_mps"] == 95.0
    assert seg0["unstable_times_s"] == [1.0]
    # each worst with its crossover (the peak for bending): the t = 0 row's frequencies
    assert seg0["worst"] == {
        "gm_low_db": {"worst": 20.0, "unit": "dB", "t_s": 0.0, "w_radps": 0.1},
        "gm_high_db": {"worst": 21.0, "unit": "dB", "t_s": 0.0, "w_radps": 5.0},
        "pm_deg": {"worst": 28.0, "unit": "deg", "t_s": 0.0, "w_radps": 2.0},
        "bending_1": {"worst": -20.0, "unit": "dB", "t_s": 0.0, "w_radps": 30.0},
        "bending_2": {"worst": -25.0, "unit": "dB", "t_s": 0.0, "w_radps": 70.0}}
    assert seg1["interval_s"] == [5.0, 5.0] and seg1["v_sched_mps"] == 1780.0
    assert seg1["unstable_times_s"] == [5.0]
    assert all(w["worst"] is None and w["t_s"] is None for w in seg1["worst"].values())
    # the loops flown inside the grid: t = 2, 3, 4 (all passing)
    inside = s["nominal_controller_not_clamped"]
    assert inside["stability"]["n_loops"] == 3
    assert inside["pm_deg"] == {"worst": 52.0, "unit": "deg", "pass": True, "n_fail_times": 0,
                                "fail_intervals_s": [], "t_s": 2.0, "corner": 0,
                                "w_radps": 4.0}
    assert "dispersed" not in s
    json.dumps(s, allow_nan=False)                           # strict JSON
    # the given times are the ones reported; no table: no table entry
    s2 = M.summarise(result, None, times=[0.0, 0.5, 1.0, 9.0])
    assert s2["times_s"] == {"first": 0.0, "last": 9.0, "n": 4}
    assert "table" not in s2
    assert s2["nominal"]["clamped_intervals_s"] == [[0.0, 0.0], [1.0, 1.0]]


def test_summarise_all_clamped_has_no_inside_verdict():
    s = M.summarise({"rows": [_row(0, clamped=True), _row(1, clamped=True)],
                     "corners": [{}]})
    assert s["nominal_controller_not_clamped"] is None
    assert s["run_time_s"] is None and s["workers"] is None
    assert s["nominal"]["clamped_segments"][0]["worst"]["pm_deg"] == {
        "worst": 50.0, "unit": "deg", "t_s": 0.0, "w_radps": 2.0}
    assert s["nominal"]["nyquist_disagreements"] == 0


def test_summarise_dispersed_families_by_hand():
    corners = [{"thrust": 0.0, "jyy": 0.0}] + [{"thrust": 0.05, "jyy": 0.0}] * 640 + [
        {"thrust": 0.0, "jyy": M.JYY_TABLE_2_3}]
    assert len(corners) == 642
    rows = []
    for t, clamped in ((0.0, True), (1.0, False)):
        rows += [_row(t, 0, clamped=clamped),
                 _row(t, 7, clamped=clamped, gm_low_db=4.0 + t),      # rigid: fails 6, not 3
                 _row(t, 600, clamped=clamped, **_bending(-4.0, 25.0, 5.0)),  # bending
                 _row(t, 641, clamped=clamped, pm_deg=19.0 + t)]      # off-nominal
    s = M.summarise({"rows": rows, "corners": corners})
    d = s["dispersed"]
    assert d["corners"] == {
        "n": 642, "rigid": list(M.RIGID_CORNER_NAMES), "bending": list(M.BENDING_CORNER_NAMES),
        "bending_loop": list(M.BENDING_LOOP_NAMES),
        "doc": M.dispersed_corners.__doc__.split("\n\n")[1].strip()}
    assert d["corners"]["doc"].startswith("* corner 0: the nominal plant;")
    assert d["corners"]["doc"].endswith("must stay stable too (docs/FLIGHT_DESIGN.md §5).")
    assert d["scheduling"] == ("the controller is interpolated at the nominal velocity of each "
                               "time")
    assert d["dispersed_criterion"] == {"gm_db": 3.0, "pm_deg": 20.0, "bending_db": -3.0,
                                        "bending_phase_pm_deg": 20.0,
                                        "bending_phase_gm_db": 3.0}
    fams = d["families"]
    assert list(fams) == ["all", "rigid", "bending", "offnominal"]
    assert [fams[f]["n_plants_per_time"] for f in fams] == [4, 1, 1, 1]
    assert [fams[f]["requirements"]["stability"]["n_loops"] for f in fams] == [8, 2, 2, 2]
    rig = fams["rigid"]
    assert rig["requirements"]["gm_low_db"]["pass"] is False
    assert rig["requirements"]["gm_low_db"]["n_fail_times"] == 2
    assert rig["requirements"]["gm_low_db"]["worst"] == 4.0
    assert rig["requirements"]["gm_low_db"]["deviations"] == {"thrust": 0.05}
    assert rig["dispersed_criterion"]["gm_low_db"]["pass"] is True
    assert rig["dispersed_criterion"]["gm_low_db"]["deviations"] == {"thrust": 0.05}
    assert rig["requirements_controller_not_clamped"]["gm_low_db"]["worst"] == 5.0
    assert rig["requirements_controller_not_clamped"]["gm_low_db"]["family"] == "rigid"
    assert rig["requirements_controller_not_clamped"]["stability"]["n_loops"] == 1
    ben = fams["bending"]
    assert ben["requirements"]["bending_1"]["pass"] is False
    assert ben["dispersed_criterion"]["bending_1"]["pass"] is True
    assert ben["requirements"]["bending_1"]["family"] == "bending"
    off = fams["offnominal"]
    assert off["requirements"]["pm_deg"]["worst"] == 19.0
    assert off["requirements"]["pm_deg"]["deviations"] == {"jyy": M.JYY_TABLE_2_3}
    assert off["dispersed_criterion"]["pm_deg"]["fail_intervals_s"] == [[0.0, 0.0]]
    assert off["requirements_controller_not_clamped"]["pm_deg"]["worst"] == 20.0
    every = fams["all"]["requirements"]
    assert every["pm_deg"]["family"] == "offnominal" and every["pm_deg"]["corner"] == 641
    assert every["gm_low_db"]["family"] == "rigid" and every["gm_low_db"]["corner"] == 7
    # the nominal verdict reads corner 0 only
    assert s["nominal"]["stability"]["n_loops"] == 2 and s["nominal"]["pm_deg"]["pass"]


def test_summarise_dispersed_family_all_clamped():
    corners = [{"x": 0.0}, {"x": 0.1}]
    rows = [_row(0, 0, clamped=True), _row(0, 1, clamped=True)]
    fams = M.summarise({"rows": rows, "corners": corners})["dispersed"]["families"]
    assert fams["rigid"]["requirements_controller_not_clamped"] is None
    assert fams["bending"]["n_plants_per_time"] == 0


# -------------------------------------------------------------------- JSON and CSV output
def test_json_ready_by_hand():
    obj = {1: np.float64(2.5), "a": [np.inf, -np.inf, np.nan, 3.0, np.int64(4)],
           "b": (np.bool_(True), False, np.float32(0.5)), "c": np.array([1.0, np.inf]),
           "d": {"e": "text", "f": None, "g": np.int32(-7), "h": True}}
    got = M.json_ready(obj)
    assert got == {"1": 2.5, "a": [None, None, None, 3.0, 4], "b": [True, False, 0.5],
                   "c": [1.0, None], "d": {"e": "text", "f": None, "g": -7, "h": True}}
    assert type(got["a"][4]) is int and type(got["b"][0]) is bool
    assert type(got["1"]) is float and type(got["d"]["g"]) is int
    assert type(got["d"]["h"]) is bool and type(got["b"][1]) is bool
    assert json.loads(json.dumps(got, allow_nan=False)) == got
    assert M.json_ready(np.float64(np.nan)) is None and M.json_ready(7) == 7


@pytest.mark.parametrize("x, text", [
    (None, ""), (True, "1"), (False, "0"), (np.bool_(True), "1"), (np.bool_(False), "0"),
    (3, "3"), (np.int64(-12), "-12"), ("nominal", "nominal"), (1.0 / 3.0, "0.333333"),
    (1234567.0, "1.23457e+06"), (np.float32(0.25), "0.25"), (INF, "inf"), (-INF, "-inf"),
    (2.0, "2")])
def test_fmt_by_hand(x, text):
    assert M._fmt(x) == text


def test_write_csv_by_hand(tmp_path):
    path = tmp_path / "m.csv"
    rows = [{"t_s": 0.5, "corner": 0, "clamped": True, "pm_deg": 31.123456789},
            {"t_s": 1.0, "corner": 3, "clamped": np.bool_(False), "extra": 9}]
    M.write_csv(path, rows, columns=("t_s", "corner", "clamped", "pm_deg"))
    assert path.read_text(encoding="utf-8") == ("t_s,corner,clamped,pm_deg\n"
                                                "0.5,0,1,31.1235\n"
                                                "1,3,0,\n")
    M.write_csv(path, rows[:1])
    lines = path.read_text().splitlines()
    assert lines[0] == ",".join(M.CSV_COLUMNS) and len(lines) == 2
    cells = lines[1].split(",")
    assert len(cells) == len(M.CSV_COLUMNS) == 48
    assert cells[:4] == ["0.5", "0", "", "1"] and cells[14] == "31.1235"
    assert cells[4:14] == [""] * 10 and cells[15:] == [""] * 33


# ------------------------------------------------------------------------ small helpers
@pytest.mark.parametrize("dev, label", [
    ({"thrust": 0.05, "mass": -0.02, "jyy": 0.0}, "thrust+ mass-"),
    ({"delay_s": -0.01}, "delay_s-"), ({"x": 1e-9}, "x+"),
    ({"a": 0.0, "b": 0.0}, "nominal"), ({}, "nominal")])
def test_corner_label_by_hand(dev, label):
    assert M.corner_label(dev) == label


def test_corner_family_boundaries():
    # 2^9 rigid corners after the nominal one, then 2^7 bending ones, then the off-nominal
    expected = {0: "nominal", 1: "rigid", 511: "rigid", 512: "rigid", 513: "bending",
                639: "bending", 640: "bending", 641: "offnominal", 642: "offnominal"}
    assert {i: M.corner_family(i) for i in expected} == expected


def test_default_times_by_hand():
    times = M.default_times()
    assert len(times) == 201
    assert times[:3] == [0.0, 0.5, 1.0] and times[-1] == 100.0
    assert np.allclose(np.diff(times), 0.5)


def test_total_delay_by_hand():
    vehicle = {"delays.sensor_s": 0.012, "delays.computing_s": 0.012,
               "delays.actuator_s": 0.015}
    assert M.total_delay_s(vehicle) == pytest.approx(0.039, abs=1e-15)
    assert M.total_delay_s(vehicle, 0.01) == pytest.approx(0.049, abs=1e-15)
    assert M.total_delay_s(vehicle, -0.01) == pytest.approx(0.029, abs=1e-15)
    assert M.total_delay_s({"delays.sensor_s": 1.0, "delays.computing_s": 10.0,
                            "delays.actuator_s": 100.0}, 1000) == 1111.0


def test_single_thread_blas_sets_and_restores(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "4")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "2")
    with M.single_thread_blas():
        assert [os.environ.get(n) for n in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                            "MKL_NUM_THREADS")] == ["1", "1", "1"]
    assert os.environ["OPENBLAS_NUM_THREADS"] == "4" and os.environ["MKL_NUM_THREADS"] == "2"
    assert "OMP_NUM_THREADS" not in os.environ
    with pytest.raises(RuntimeError):
        with M.single_thread_blas():
            raise RuntimeError("inside")
    assert os.environ["OPENBLAS_NUM_THREADS"] == "4" and "OMP_NUM_THREADS" not in os.environ


@pytest.mark.parametrize("n", [(1500, 4000, 200), (7, 11, 5)])
def test_frequency_grid_by_hand(n):
    n_rigid, n_dense, n_top = n
    w1, w2, T = 30.0, 70.0, 0.02
    w = M.frequency_grid((w1, w2), T, n_rigid, n_dense, n_top)
    top = math.pi / T * (1 - 1e-9)
    assert w.size == n_rigid + n_dense + n_top - 1
    assert w[0] == pytest.approx(1e-3, rel=1e-12)
    assert w[n_rigid] == pytest.approx(0.55 * w1, rel=1e-12)        # dense part starts
    assert w[n_rigid - 1] < 0.55 * w1
    assert w[n_rigid + n_dense - 1] == pytest.approx(1.5 * w2, rel=1e-12)
    assert w[-1] == pytest.approx(top, rel=1e-12) and w[-1] < math.pi / T
    assert np.all(np.diff(w) > 0)
    # log-uniform in each part
    r = np.diff(np.log(w[:n_rigid + 1]))
    assert np.allclose(r, math.log(0.55 * w1 / 1e-3) / n_rigid)
    r = np.diff(np.log(w[n_rigid:n_rigid + n_dense]))
    assert np.allclose(r, math.log(1.5 * w2 / (0.55 * w1)) / (n_dense - 1))
    r = np.diff(np.log(w[n_rigid + n_dense - 1:]))
    assert np.allclose(r, math.log(top / (1.5 * w2)) / (n_top - 1))


def test_frequency_grid_without_a_top_part():
    """1.5 ω₂ above the Nyquist frequency: the grid ends at 1.5 ω₂."""
    w = M.frequency_grid((30.0, 120.0), 0.02, 10, 20, 5)
    assert w.size == 30 and w[-1] == pytest.approx(180.0, rel=1e-12)
    w = M.frequency_grid((30.0, 157.07963 / 1.5 + 1e-3), 0.02, 10, 20, 5)
    assert w.size == 30                     # b just above π/T·(1 − 1e-9): no top part


def test_max_q_time_against_the_raw_table():
    """The flight-condition CSV parsed here (comment lines, header, rows): the time of the
    largest q_pa."""
    from vega_model.flight_conditions import default_flight_conditions_path
    from vega_model.parameters import default_context

    lines = [ln for ln in default_flight_conditions_path().read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    names = lines[0].split(",")
    data = np.array([[float(c) for c in ln.split(",")] for ln in lines[1:]])
    q, t = data[:, names.index("q_pa")], data[:, names.index("t_s")]
    k = max(range(len(q)), key=lambda i: q[i])
    assert M.max_q_time(default_context()) == t[k]
    assert 30.0 < t[k] < 70.0 and q[k] > q[0] and q[k] > q[-1]


def test_frequency_grid_when_1_5_omega_2_is_exactly_the_top():
    """1.5 ω₂ exactly at π/T·(1 − 1e-9): the grid ends there, no repeated top samples."""
    T = 0.02
    top = math.pi / T * (1.0 - 1e-9)
    w2 = top / 1.5
    for _ in range(50):
        if 1.5 * w2 == top:
            break
        w2 = np.nextafter(w2, np.inf if 1.5 * w2 < top else -np.inf)
    assert 1.5 * w2 == top
    w = M.frequency_grid((30.0, w2), T, 10, 20, 5)
    assert w.size == 30 and w[-1] == top and np.all(np.diff(w) > 0)
