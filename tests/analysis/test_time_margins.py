"""Time-domain margins (vega_analysis.time_margins) and the loop-perturbation hook of the
in-process closed loop (vega_sim.closed_loop.LoopPerturbation), on the shipped table.

The hook is checked against its definition (the command the actuator holds over every 1 ms
step, rebuilt here from the controller's recorded commands), the verdict on
flights that are plainly stable and plainly lost, and the bisection against the
frequency-domain margin of the same loop (vega_loops.margins.analyse_loop). Short
windows and flights keep the run time small (about 20 flights in all).
"""

import csv
import dataclasses
import math

import numpy as np
import pytest

from vega_loops import margins as M
from vega_analysis import time_margins as T
from vega_gnc.controller_table import default_table_path, load_controller_table
from vega_sim.assembly import loop_timing
from vega_sim.closed_loop import LoopPerturbation, run_scenario
from vega_sim.scenario import load_scenario

# a short flight with the shipped table: lift-off to 6 s (commands every 20 ms, stamps 24 + 20k)
SHORT_END_S = 6.0
WINDOW_MS = (2000, 4000)


@pytest.fixture(scope="module")
def table():
    return load_controller_table(default_table_path())


@pytest.fixture(scope="module")
def context():
    from vega_model.parameters import default_context

    return default_context()


@pytest.fixture(scope="module")
def short():
    return dataclasses.replace(load_scenario("nominal"), t_end_s=SHORT_END_S)


@pytest.fixture(scope="module")
def plain(short, table):
    return run_scenario(short, table)


def _identical(a, b) -> bool:
    arrays_a, arrays_b = a.arrays(), b.arrays()
    return arrays_a.keys() == arrays_b.keys() and all(
        np.array_equal(arrays_a[k], arrays_b[k]) for k in arrays_a)


def in_force(result, latency_ms, at_ms):
    """β_c: the controller's command the unperturbed actuator holds from ``at_ms`` on (the
    newest with stamp + latency <= at_ms; the initial nozzle angle before the first)."""
    k = np.searchsorted(result.cmd_stamp_ms + latency_ms, at_ms, side="right") - 1
    return np.where(k >= 0, result.cmd_rad[np.maximum(k, 0)], result.beta_cmd_rad[0])


def step_starts(result):
    """Start of the 1 ms physics step ending at each actuator sample act_t_ms[1:]."""
    return result.act_t_ms[1:] - 1


# ------------------------------------------------------------------------------------ hook
@pytest.mark.slow
def test_hook_that_changes_nothing_is_bit_identical(short, table, plain):
    """Off (None), unit gain without delay, or a window after the flight: the very same run."""
    assert _identical(run_scenario(short, table, perturbation=None), plain)
    assert _identical(run_scenario(short, table,
                                   perturbation=LoopPerturbation(*WINDOW_MS, 1.0, 0)), plain)
    late = LoopPerturbation(int(SHORT_END_S * 1000) + 100, int(SHORT_END_S * 1000) + 500,
                            gain=7.0, delay_ms=90)
    assert _identical(run_scenario(short, table, perturbation=late), plain)


def test_gain_scales_exactly_the_actuator_input_in_the_window(short, table, plain):
    """Inside [t0, t1) the actuator holds k × the controller's command in force, outside
    exactly that command (the hook's definition, rebuilt here from the recorded commands)."""
    k = 1.7
    t0, t1 = WINDOW_MS
    run = run_scenario(short, table, perturbation=LoopPerturbation(t0, t1, gain=k))
    latency = loop_timing(short).actuator_latency_ms
    s = step_starts(run)
    inside = (s >= t0) & (s < t1)
    assert inside.sum() == t1 - t0
    assert np.array_equal(run.beta_cmd_rad[1:][inside], k * in_force(run, latency, s[inside]))
    assert np.array_equal(run.beta_cmd_rad[1:][~inside], in_force(run, latency, s[~inside]))
    # before t0 the flight is the plain one, bit for bit; from t0 on the nozzle differs
    before = run.act_t_ms <= t0
    assert np.array_equal(run.beta_rad[before], plain.beta_rad[before])
    assert np.array_equal(run.cmd_rad[run.cmd_stamp_ms + latency <= t0],
                          plain.cmd_rad[plain.cmd_stamp_ms + latency <= t0])
    assert not np.array_equal(run.beta_rad, plain.beta_rad)


def test_delay_shifts_the_actuator_input_by_delta_in_the_window(short, table, plain):
    """Inside [t0, t1) every 1 ms sample of the held command is the one Δ earlier (the
    controller's commands as the unperturbed actuator would hold them); outside, no delay."""
    delay = 45                                   # not a multiple of the 20 ms command period
    t0, t1 = WINDOW_MS
    run = run_scenario(short, table, perturbation=LoopPerturbation(t0, t1, delay_ms=delay))
    latency = loop_timing(short).actuator_latency_ms
    s = step_starts(run)
    inside = (s >= t0) & (s < t1)
    held = run.beta_cmd_rad[1:]
    assert np.array_equal(held[inside], in_force(run, latency, s[inside] - delay))
    assert np.array_equal(held[~inside], in_force(run, latency, s[~inside]))
    assert not np.array_equal(held[inside], in_force(run, latency, s[inside]))
    # the samples of the window are those of Δ earlier in an undelayed actuator's input:
    # the same command sequence, each switch Δ ms later
    switches = s[inside][np.flatnonzero(np.diff(held[inside])) + 1]
    applied = run.cmd_stamp_ms + latency
    assert set(switches - delay) <= set(applied)
    assert len(switches) >= (t1 - t0) // 20 - 2


def test_a_bad_perturbation_is_refused():
    for bad in (dict(t0_ms=10, t1_ms=5), dict(t0_ms=0, t1_ms=5, delay_ms=-1),
                dict(t0_ms=0, t1_ms=5, gain=math.inf), dict(t0_ms=0.5, t1_ms=5),
                dict(t0_ms=0, t1_ms=5, delay_ms=2.5)):
        with pytest.raises(ValueError):
            LoopPerturbation(**bad)
    with pytest.raises(ValueError):
        T.perturbation(T.Segment("x", 1.0, 2.0, ""), "phase", 1.0)


# --------------------------------------------------------------------------------- segments
def test_segments_come_from_the_flight_conditions(context):
    segments = {s.name: s for s in T.SEGMENTS}
    assert list(segments) == ["lift-off", "transonic", "max-Q", "burn-out"]
    t_q = M.max_q_time(context)
    assert segments["max-Q"].t0_s < t_q < segments["max-Q"].t1_s
    transonic = segments["transonic"]
    assert context.parameters(transonic.t0_s).mach >= 0.8
    assert context.parameters(transonic.t0_s - 0.1).mach < 0.8
    assert context.parameters(transonic.t1_s - 0.1).mach <= 1.2 < context.parameters(
        transonic.t1_s).mach
    assert segments["lift-off"].t0_s == 0.0
    assert segments["burn-out"].t1_s + T.SETTLE_S <= 100.0
    for s in segments.values():
        assert s.source and 0.0 < s.t1_s - s.t0_s <= 10.5
        assert s.t0_ms == round(1000 * s.t0_s) and s.t1_ms == round(1000 * s.t1_s)


# ---------------------------------------------------------------------------------- verdict
@pytest.mark.slow
def test_verdict_passes_the_nominal_flight_and_flags_a_lost_one(table):
    nominal = T.flight_stability(run_scenario("nominal", table))
    assert nominal["stable"] and nominal["failed"] == ""
    assert nominal["rate_limited_s"] == 0.0 and nominal["controller_limited_s"] == 0.0
    at_max_q = T.Segment("max-Q test", 46.0, 48.0, "test")
    lost = T.fly_perturbed(table, at_max_q, "gain_up", 20.0, settle_s=2.0)   # k = 10
    verdict = T.flight_stability(lost)
    assert not verdict["stable"]
    assert "rate_limited_s" in verdict["failed"].split(",")
    # a flight whose state ran away numerically is lost, whatever the other criteria say
    theta = lost.theta_rad.copy()
    theta[-1] = np.nan
    diverged = T.flight_stability(dataclasses.replace(lost, theta_rad=theta))
    assert not diverged["stable"] and diverged["failed"] == "diverged"


# -------------------------------------------------------------------------------- bisection
@pytest.mark.slow
def test_gain_margin_up_brackets_the_frequency_domain_one(table, context):
    """Bisection at max-Q on a 5 s window: the flight stays stable at the margin and is lost
    0.25 dB above; the margin lies within a few dB of the smallest frozen-loop gain margin in
    the window, and above it less a little (a loop frozen-unstable over the whole window
    diverges; just beyond the margin it diverges slowly, so the time-domain margin is higher)."""
    segment = T.Segment("max-Q test", 45.0, 50.0, "test")
    res = T.bisect_margin(table, segment, "gain_up", bracket=12.0, tol=0.25)
    assert res["found"] and res["unit"] == "dB"
    assert 0.0 < res["unstable_at"] - res["margin"] <= 0.25
    assert res["flights"] == 2 + math.ceil(math.log2(12.0 / 0.25))
    fd = min(M.analyse_time(table, context, t, [(0, {})], nyquist=False)[0]["gm_high_db"]
             for t in np.arange(45.0, 50.01, 0.5))
    assert 5.0 < fd < 9.0                   # the shipped design: ≈ 6 dB at max-Q
    assert fd - 0.5 <= res["margin"] <= fd + 3.0, (res, fd)


@pytest.mark.slow
def test_delay_margin_and_outputs(table, context, tmp_path):
    """The whole API on one short max-Q window, delay only, coarse tolerance: the time-domain
    delay margin is not below the frozen one, the rows, CSV and markdown carry it, and the
    progress callback hears once per finished task."""
    segment = T.Segment("max-Q test", 45.0, 50.0, "test window")
    lines = []
    rows = T.time_domain_margins(default_table_path(), segments=[segment], workers=0,
                                 progress=lines.append, kinds=("delay",),
                                 brackets={"delay": 1000}, tols={"delay": 50})
    assert len(rows) == 1 and len(lines) == 2
    row = rows[0]
    assert row["dm_found"] and 0 < row["dm_unstable_ms"] - row["dm_ms"] <= 50
    assert row["flights"] == row["dm_flights"] == 2 + math.ceil(math.log2(1000 / 50))
    assert 150.0 < row["fd_dm_ms"] < 400.0            # the shipped design: 180–290 ms at max-Q
    assert row["dm_ms"] >= row["fd_dm_ms"] - 50.0, row
    assert "gm_up_db" not in row and row["t_end_s"] == 50.0 + T.SETTLE_S
    # each frequency-domain margin names its crossover: the frozen loop at the margin's time
    # recomputed here gives the same frequency (the PM: the distance from −180° at or above
    # the frozen-time floor)
    for stem, key in (("fd_gm_up", "gm_high_db"), ("fd_gm_down", "gm_low_db"),
                      ("fd_pm", "pm_deg")):
        t = row[f"{stem}_t_s"]
        data = M.loop_data(table, context, t)
        loop = M.frozen_loop(data, *M.corner_plant(context, t, {}))
        ref = M.extract_margins(data.w_radps, loop.L, loop.omega_modes)
        assert row[f"{stem}_w_radps"] == pytest.approx(ref[M.FREQUENCY_OF[key]], rel=1e-12)
    assert row["fd_pm_w_radps"] >= M.PM_FLOOR_RADPS
    path = tmp_path / "time_margins.csv"
    T.write_csv(path, rows)
    with open(path, newline="", encoding="utf-8") as f:
        back = list(csv.DictReader(f))
    assert [r["segment"] for r in back] == ["max-Q test"]
    assert float(back[0]["dm_ms"]) == row["dm_ms"] and back[0]["gm_up_db"] == ""
    assert float(back[0]["fd_pm_w_radps"]) == pytest.approx(row["fd_pm_w_radps"], rel=1e-5)
    table_md = T.markdown(rows)
    assert (f"| {row['dm_ms']:.0f} / {row['fd_dm_ms']:.0f} @{row['fd_dm_w_radps']:.3g} |"
            in table_md)
    assert f"| {row['fd_pm_deg']:.1f} @{row['fd_pm_w_radps']:.3g} |" in table_md


@pytest.mark.slow
def test_workers_do_not_change_the_result_and_a_margin_beyond_the_bracket(table):
    """Lift-off: too little gain does not lose the flight down to k = 0.1 in 4 s (no
    aerodynamic moment to speak of at Mach < 0.2), reported as beyond the bracket; the same
    rows from one spawned worker as in this process."""
    segment = T.Segment("lift-off test", 0.0, 4.0, "test")
    kwargs = dict(segments=[segment], kinds=("gain_down",), settle_s=1.0,
                  frequency_domain=False)
    here = T.time_domain_margins(default_table_path(), workers=0, **kwargs)
    spawned = T.time_domain_margins(default_table_path(), workers=1, **kwargs)
    assert here == spawned
    row = here[0]
    assert not row["gm_down_found"] and row["gm_down_db"] == T.GAIN_BRACKET_DB
    assert row["gm_down_unstable_db"] == math.inf and row["gm_down_flights"] == 2
    assert "> 20.0" in T.markdown(here)
