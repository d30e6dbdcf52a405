"""The bag checker's pieces (vega_bags.bagcheck), tested for `make mutation MODULE=bagcheck`.

One short in-process flight (thesis scenario, 20.0 … 20.5 s, PD fixture table) is written to a
bag and read back once; faults are then injected into the columns of that loaded bag in memory
(no flight, no bag written per test), so each check is exercised on its own.

Independent references: the schedule of a 0.5 s run typed out by hand from the loop timing
(vehicle.yaml: 10 ms frames, 20 ms controller period, 12 ms sensor and computing latency,
15 ms actuator latency, 1 ms physics step): truth 51 messages 20.000 … 20.500 s, INS 50 at
sample + 12 ms, actuator 50 frames stamped 20.010 … 20.500 s of 10 samples each, 25 commands
sampled 20.000 … 20.480 s and stamped 24 ms later, /clock at 20.0, 20.1, … 20.5 s; the
in-process run's own arrays (the bag must give them back bit for bit); console and JSON text
typed out by hand; percentiles and medians of small hand arrays.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from cached_bags import cached_short_run
from vega_bags import bagcheck, bagio
from vega_bus import topics
from vega_bus.schedule import RunInfo
from vega_bus.timing import LoopTiming

MS = 1_000_000  # ns
TIMING = LoopTiming(physics_dt_ms=1, frame_ms=10, controller_period_ms=20, sensor_latency_ms=12,
                    computing_latency_ms=12, actuator_latency_ms=15)
TRUTH, INS, CMD, ACT, DIAG, CLOCK = (t.name for t in (
    topics.TRUTH, topics.INS, topics.TVC_CMD, topics.ACTUATOR, topics.DIAGNOSTICS,
    topics.CLOCK))


@pytest.fixture(scope="module")
def small():
    """(the in-process run, its bag directory, the loaded bag); flown once per set of inputs
    (tests/bags/cached_bags.py)."""
    run, path = cached_short_run((20.0, 20.5))
    return run, path, bagio.read_run_bag(path)


def _edit(bag, topic, log_time_ns=None, **columns):
    """The bag with some columns (and/or the log times) of one topic replaced."""
    cols = bag[topic]
    new = dataclasses.replace(cols, columns={**cols.columns, **columns},
                              log_time_ns=cols.log_time_ns if log_time_ns is None
                              else log_time_ns)
    return dataclasses.replace(bag, topics={**bag.topics, topic: new})


def _take(bag, topic, n):
    """The bag with only the first ``n`` messages of a topic of fixed-size fields."""
    cols = bag[topic]
    assert not cols.counts
    new = dataclasses.replace(cols, log_time_ns=cols.log_time_ns[:n],
                              columns={k: v[:n] for k, v in cols.columns.items()})
    return dataclasses.replace(bag, topics={**bag.topics, topic: new})


def _without(bag, topic):
    return dataclasses.replace(bag, topics={k: v for k, v in bag.topics.items() if k != topic})


def _meta(bag, **changes):
    meta = dict(bag.metadata)
    for k, v in changes.items():
        key = getattr(bagio, k)
        if v is None:
            meta.pop(key, None)
        else:
            meta[key] = v
    return dataclasses.replace(bag, metadata=meta)


def _stamps_ms(bag, topic, field="stamp_ns"):
    return (bag[topic][field] // MS).tolist()


# ----------------------------------------------------------------------------- the fixture bag
def test_the_bag_holds_the_hand_schedule(small):
    """The reference schedule itself (the rest of this file relies on it)."""
    _, _, bag = small
    assert _stamps_ms(bag, TRUTH) == list(range(20000, 20501, 10))
    assert _stamps_ms(bag, INS, "sample_stamp_ns") == list(range(20000, 20491, 10))
    assert _stamps_ms(bag, INS) == list(range(20012, 20503, 10))
    assert _stamps_ms(bag, ACT) == list(range(20010, 20501, 10))
    assert _stamps_ms(bag, CMD, "sample_stamp_ns") == list(range(20000, 20481, 20))
    assert _stamps_ms(bag, CMD) == list(range(20024, 20505, 20))
    assert _stamps_ms(bag, DIAG) == list(range(20024, 20505, 20))
    assert _stamps_ms(bag, CLOCK) == list(range(20000, 20501, 100))
    assert bag[ACT].counts["deflection_samples_rad"].tolist() == [10] * 50


# ----------------------------------------------------------------------------- run_context
def test_run_context_of_a_complete_bag(small):
    run, _, bag = small
    ctx = bagcheck.run_context(bag)
    sc = run.result.scenario
    assert ctx.scenario == sc and ctx.problems == ()
    assert ctx.timing == TIMING
    assert ctx.info == RunInfo("thesis", run.result.seed, 20000, 20500, TIMING, sc.guidance)
    assert ctx.t_start_ms == 20000
    assert ctx.beta0_rad == float(sc.initial_state.beta_rad)


def test_run_context_seed_from_the_metadata(small):
    run, _, bag = small
    assert bagcheck.run_context(_meta(bag, META_SEED="7")).info.seed == 7
    # not a non-negative integer: the scenario's own seed
    for seed in ("-3", "x", ""):
        ctx = bagcheck.run_context(_meta(bag, META_SEED=seed))
        assert ctx.info.seed == run.result.scenario.seed, seed


def test_run_context_names_every_missing_key(small):
    run, _, bag = small
    ctx = bagcheck.run_context(_meta(bag, META_SEED=None, META_GIT_REVISION=None))
    assert ctx.problems == ("missing vega.seed", "missing vega.git_revision")
    assert bagcheck._check_metadata(ctx).detail == "missing vega.seed; missing vega.git_revision"
    assert ctx.info.seed == run.result.scenario.seed and ctx.scenario is not None


def test_run_context_without_a_usable_scenario(small):
    from vega_model.vehicle_data import load_vehicle_data

    _, _, bag = small
    ctx = bagcheck.run_context(_meta(bag, META_SCENARIO_YAML=None))
    assert ctx == bagcheck.RunContext(None, LoopTiming.from_vehicle(load_vehicle_data()), None,
                                      0.0, ("missing vega.scenario_yaml",))
    assert ctx.t_start_ms is None and ctx.timing == TIMING
    ctx = bagcheck.run_context(_meta(bag, META_SCENARIO_YAML="name: [unclosed"))
    assert ctx.scenario is None and ctx.info is None and ctx.beta0_rad == 0.0
    (problem,) = ctx.problems
    assert "metadata vega.scenario_yaml" in problem and "\n" not in problem
    h = bagcheck._check_metadata(ctx)
    assert h == bagcheck.HealthResult("metadata", "metadata", "incomplete",
                                      "run metadata + scenario", False, problem)


# ----------------------------------------------------------------------------- the run
def _act(stamps_ms, counts, periods_s):
    n = int(sum(counts))
    return bagio.TopicColumns(ACT, "", np.asarray(stamps_ms, np.int64) * MS, {
        "stamp_ns": np.asarray(stamps_ms, np.int64) * MS,
        "sample_period_s": np.asarray(periods_s, float),
        "deflection_samples_rad": np.arange(n, dtype=float)},
        {"deflection_samples_rad": np.asarray(counts, np.int64)})


def test_actuator_sample_instants_by_hand():
    """Sample j of k in a frame stamped S lies at S − (k−1−j)·dt."""
    got = bagcheck._actuator_times_ms(_act([100, 105], [3, 2], [0.001, 0.002]))
    assert got.tolist() == [98, 99, 100, 103, 105]
    got = bagcheck._actuator_times_ms(_act([50, 60, 70], [1, 4, 2], [0.005, 0.002, 0.010]))
    assert got.tolist() == [50, 54, 56, 58, 60, 60, 70]
    assert bagcheck._actuator_times_ms(_act([], [], [])).tolist() == []
    # the period is rounded to whole ms from seconds: 0.75 s is 750 ms
    got = bagcheck._actuator_times_ms(_act([3000], [3], [0.75]))
    assert got.tolist() == [1500, 2250, 3000]


def _cmd(stamps_ms, values):
    return bagio.TopicColumns(CMD, "", np.asarray(stamps_ms, np.int64) * MS, {
        "stamp_ns": np.asarray(stamps_ms, np.int64) * MS,
        "deflection_cmd_rad": np.asarray(values, float)})


def test_held_command_by_hand():
    """A command stamped S acts from S + 15 ms (actuator latency) on the physics step ending
    at t, i.e. when t − 1 ms ≥ S + 15 ms; before the first one, β(t_start)."""
    ctx = bagcheck.RunContext(None, TIMING, None, -0.125)
    t = np.array([30, 39, 40, 41, 59, 60, 61, 80], np.int64)
    held = bagcheck._held_command_rad(_cmd([24, 44], [0.1, 0.2]), t, 1, ctx)
    assert held.tolist() == [-0.125, -0.125, 0.1, 0.1, 0.1, 0.2, 0.2, 0.2]
    # a 2 ms step: t − 2 ms is compared
    held = bagcheck._held_command_rad(_cmd([24, 44], [0.1, 0.2]), t, 2, ctx)
    assert held.tolist() == [-0.125, -0.125, -0.125, 0.1, 0.1, 0.1, 0.2, 0.2]
    # a non-finite command holds the previous one
    held = bagcheck._held_command_rad(_cmd([24, 44, 64], [0.1, math.nan, 0.3]),
                                      np.array([60, 80, 90], np.int64), 1, ctx)
    assert held.tolist() == [0.1, 0.3, 0.3]
    # a stamp between whole ms counts from the ms it falls in (24.9 ms → from 24 + 15 = 39 ms)
    cmd = bagio.TopicColumns(CMD, "", np.array([24_900_000], np.int64), {
        "stamp_ns": np.array([24_900_000], np.int64), "deflection_cmd_rad": np.array([0.1])})
    held = bagcheck._held_command_rad(cmd, np.array([39, 40], np.int64), 1, ctx)
    assert held.tolist() == [-0.125, 0.1]
    # nothing usable: β(t_start) throughout
    for cmd in (None, _cmd([], []), _cmd([24], [math.inf])):
        held = bagcheck._held_command_rad(cmd, t, 1, ctx)
        assert held.tolist() == [-0.125] * t.size


def test_bag_result_is_the_in_process_run(small):
    run, _, bag = small
    got = bagcheck.bag_result(bag)
    assert got.scenario == run.result.scenario and got.seed == run.result.seed
    want, have = run.result.arrays(), got.arrays()
    assert have.keys() == want.keys()
    for name, value in want.items():
        assert have[name].dtype == value.dtype, name
        assert np.array_equal(have[name], value), name
    # by hand: β(t_start) first, then 10 samples per frame
    assert got.act_t_ms[:3].tolist() == [20000, 20001, 20002] and got.act_t_ms.size == 501
    assert got.beta_rad[0] == run.result.scenario.initial_state.beta_rad
    assert got.beta_dot_radps[0] == 0.0 and got.beta_ddot_radps2[0] == 0.0


def test_held_command_uses_the_first_frames_step(small):
    """The physics step of the held command is the first actuator frame's: another step in
    frame 1 changes only that frame's instants (samples 11 … 20 of the arrays)."""
    run, _, bag = small
    period = bag[ACT]["sample_period_s"].copy()
    period[1] = 0.002
    got = bagcheck.bag_result(_edit(bag, ACT, sample_period_s=period))
    want = run.result.beta_cmd_rad
    assert np.array_equal(got.beta_cmd_rad[21:], want[21:])
    assert np.array_equal(got.beta_cmd_rad[:11], want[:11])


def test_held_command_step_in_whole_ms_by_a_plain_loop(small):
    """A 0.75 s step (750 ms; ×1001 would give 751): the held command against a plain loop
    over the commands (applied from stamp + 15 ms, acting on the step ending at t when
    t − 750 ms ≥ that instant)."""
    _, _, bag = small
    period = np.full(len(bag[ACT]), 0.75)
    ctx = bagcheck.RunContext(None, TIMING, None, 0.5)
    early = bag[CMD]["stamp_ns"] - 1499 * MS       # commands 18.525 … 19.005 s
    got = bagcheck.bag_result(_edit(_edit(bag, ACT, sample_period_s=period), CMD,
                                    stamp_ns=early), ctx)
    stamps = early // MS
    values = bag[CMD]["deflection_cmd_rad"]
    want = []
    for t in got.act_t_ms:
        held = 0.5
        for s_ms, v in zip(stamps, values):
            if s_ms + 15 <= t - 750:
                held = v
        want.append(held)
    assert got.beta_cmd_rad.tolist() == want
    assert len(set(want)) > 3          # the commands change over the samples


def test_bag_result_without_a_start_time(small):
    """No scenario: the samples as recorded, nothing prepended."""
    _, _, bag = small
    ctx = bagcheck.RunContext(None, TIMING, None, 0.25)
    got = bagcheck.bag_result(bag, ctx)
    assert got.act_t_ms[:2].tolist() == [20001, 20002] and got.act_t_ms.size == 500
    assert np.array_equal(got.beta_rad, bag[ACT]["deflection_samples_rad"])
    assert np.array_equal(got.beta_dot_radps, bag[ACT]["rate_samples_radps"])
    assert np.array_equal(got.beta_ddot_radps2, bag[ACT]["accel_samples_radps2"])
    assert got.scenario is None


def test_bag_result_starting_at_t_start_prepends_nothing(small):
    _, _, bag = small
    ctx = bagcheck.run_context(bag)
    ctx = dataclasses.replace(ctx, info=dataclasses.replace(ctx.info, t_start_ms=20001))
    got = bagcheck.bag_result(bag, ctx)
    assert got.act_t_ms[0] == 20001 and got.act_t_ms.size == 500


def test_bag_result_seed_and_missing_topics(small):
    _, _, bag = small
    assert bagcheck.bag_result(_meta(bag, META_SEED="-3")).seed == -3
    assert bagcheck.bag_result(_meta(bag, META_SEED="12")).seed == 12
    assert bagcheck.bag_result(_meta(bag, META_SEED="x1")).seed == -1
    assert bagcheck.bag_result(_meta(bag, META_SEED="X5")).seed == -1
    assert bagcheck.bag_result(_meta(bag, META_SEED=None)).seed == -1
    got = bagcheck.bag_result(_without(_without(bag, INS), CMD))
    for name in ("ins_sample_ms", "ins_stamp_ms", "cmd_sample_ms", "cmd_stamp_ms", "cmd_status"):
        assert getattr(got, name).dtype == np.int64 and getattr(got, name).size == 0, name
    for name in ("ins_theta_rad", "ins_v_mps", "cmd_rad", "cmd_v_mps"):
        assert getattr(got, name).dtype == np.float64 and getattr(got, name).size == 0, name
    beta0 = bagcheck.run_context(bag).beta0_rad
    assert np.all(got.beta_cmd_rad == beta0)


@pytest.mark.parametrize("topic", [TRUTH, ACT])
def test_bag_without_truth_or_actuator_is_a_bag_error(small, topic):
    _, _, bag = small
    for broken in (_without(bag, topic), _take(bag, topic, 0) if topic == TRUTH else
                   dataclasses.replace(bag, topics={**bag.topics, ACT: dataclasses.replace(
                       bag[ACT], log_time_ns=np.zeros(0, np.int64))})):
        with pytest.raises(bagio.BagError, match=f"^bag {bag.path}: no messages on {topic}: "):
            bagcheck.bag_result(broken)


# ----------------------------------------------------------------------------- health checks
def _checks(bag):
    return {h.key: h for h in bagcheck.check_run_bag(bag).health}


def test_health_of_the_complete_bag(small):
    _, _, bag = small
    h = _checks(bag)
    HR = bagcheck.HealthResult
    assert list(h) == ["metadata", "finite", "sequence", "lockstep", "coverage",
                       "compute_time"]
    assert h["metadata"] == HR("metadata", "metadata", "complete", "run metadata + scenario",
                               True, "")
    assert h["finite"] == HR("finite", "no NaN/inf", "0", "0", True)
    assert h["sequence"] == HR("sequence", "no message gaps", "ok", "seq +1", True, "")
    assert h["lockstep"] == HR("lockstep", "no lockstep stalls", "ok",
                               "+10 ms/frame, +20 ms/cmd", True, "")
    assert h["coverage"] == HR("coverage", "run complete", "20.000 … 20.500 s",
                               "20.000 … 20.500 s", True, "")
    # simbag writes 50 µs per step
    assert h["compute_time"] == HR("compute_time", "controller compute time", "max 0.05 ms",
                                   "≤ 12 ms for ≥ 99 %", True,
                                   "median 50 µs, p99 50 µs, max 50 µs", 0.012 - 5e-5)


def test_finite_names_the_earliest_bad_value(small):
    _, _, bag = small
    pitch = bag[INS]["pitch_rad"].copy()
    pitch[5] = math.nan
    one = _edit(bag, INS, pitch_rad=pitch)
    assert bagcheck._check_finite(one) == bagcheck.HealthResult(
        "finite", "no NaN/inf", "1", "0", False, "/vega/ins pitch_rad not finite at 20.062 s")
    # a flattened sample: its message (23 → the third frame, stamped 20.030 s) is earlier
    samples = bag[ACT]["deflection_samples_rad"].copy()
    samples[23] = math.inf
    samples[24] = -math.inf
    two = _edit(one, ACT, deflection_samples_rad=samples)
    h = bagcheck._check_finite(two)
    assert (h.value, h.detail) == ("3", "/vega/actuator deflection_samples_rad not finite at "
                                        "20.030 s")
    # a sample at the end of a frame belongs to that frame (index 9: the first, 20.010 s)
    samples = bag[ACT]["deflection_samples_rad"].copy()
    samples[9] = math.nan
    h = bagcheck._check_finite(_edit(bag, ACT, deflection_samples_rad=samples))
    assert h.detail.endswith("not finite at 20.010 s")
    samples[9], samples[10] = 0.0, math.nan
    h = bagcheck._check_finite(_edit(bag, ACT, deflection_samples_rad=samples))
    assert h.detail.endswith("not finite at 20.020 s")
    # a 2-D field (bending modes, N × 2): the row's message
    bend = bag[TRUTH]["bending_q"].copy()
    bend[7, 1] = math.nan
    h = bagcheck._check_finite(_edit(bag, TRUTH, bending_q=bend))
    assert (h.value, h.detail) == ("1", "/vega/truth bending_q not finite at 20.070 s")
    # the later one of two topics does not replace the earlier one
    pitch = bag[INS]["pitch_rad"].copy()
    pitch[1] = math.nan   # 20.022 s
    vel = bag[TRUTH]["velocity_mps"].copy()
    vel[4] = math.nan     # 20.040 s
    h = bagcheck._check_finite(_edit(_edit(bag, INS, pitch_rad=pitch), TRUTH,
                                     velocity_mps=vel))
    assert h.detail == "/vega/ins pitch_rad not finite at 20.022 s"


def test_finite_tie_keeps_the_first_topic(small):
    """Two bad values at the same log time: the first topic of the bag's order is named."""
    _, _, bag = small
    t_ms = 20030
    vel = bag[TRUTH]["velocity_mps"].copy()
    vel[3] = math.nan                                     # truth at 20.030 s
    samples = bag[ACT]["deflection_samples_rad"].copy()
    samples[25] = math.nan                                # actuator frame 20.030 s
    bad = _edit(_edit(bag, TRUTH, velocity_mps=vel), ACT, deflection_samples_rad=samples)
    first = next(n for n in bad.topics if n in (TRUTH, ACT))
    field = "velocity_mps" if first == TRUTH else "deflection_samples_rad"
    assert bagcheck._check_finite(bad).detail == f"{first} {field} not finite at " \
                                                 f"{t_ms / 1e3:.3f} s"


def test_finite_in_a_topic_of_one_message(small):
    _, _, bag = small
    one = _take(bag, DIAG, 1)
    one = _edit(one, DIAG, compute_time_s=np.array([math.nan]))
    h = bagcheck._check_finite(one)
    assert (h.value, h.detail) == ("1", "/vega/diagnostics compute_time_s not finite at "
                                        "20.024 s")


def test_finite_ignores_integer_and_empty_columns(small):
    _, _, bag = small
    seq = bag[TRUTH]["seq"]
    assert seq.dtype.kind in "iu"
    empty = dataclasses.replace(bag[DIAG], log_time_ns=np.zeros(0, np.int64),
                                columns={k: v[:0] for k, v in bag[DIAG].columns.items()})
    h = bagcheck._check_finite(dataclasses.replace(bag, topics={**bag.topics, DIAG: empty}))
    assert h.passed and h.value == "0"


def test_sequence_problems_by_hand(small):
    _, _, bag = small
    seq = bag[INS]["seq"]
    h = bagcheck._check_sequence(_edit(bag, INS, seq=seq + 1))
    assert h == bagcheck.HealthResult("sequence", "no message gaps", "1 topic(s)", "seq +1",
                                      False, "/vega/ins starts at seq 1")
    cmd = bag[CMD]["seq"].copy()
    cmd[10:] += 1                                          # 9 → 11
    h = bagcheck._check_sequence(_edit(bag, CMD, seq=cmd))
    assert h.detail == "/vega/tvc_cmd seq 9 → 11 (gap) at 20.224 s; 1 in all"
    truth = bag[TRUTH]["seq"].copy()
    truth[3] = 2                                           # 2 → 2 → 4
    h = bagcheck._check_sequence(_edit(bag, TRUTH, seq=truth))
    assert h.detail == "/vega/truth seq 2 → 2 (repeat/out of order) at 20.030 s; 2 in all"
    truth = bag[TRUTH]["seq"].copy()
    truth[[5, 6]] = truth[[6, 5]]                          # 4 → 6 → 5 → 7
    h = bagcheck._check_sequence(_edit(bag, TRUTH, seq=truth))
    assert h.detail == "/vega/truth seq 4 → 6 (gap) at 20.050 s; 3 in all"
    both = _without(_edit(bag, INS, seq=seq + 1), DIAG)
    h = bagcheck._check_sequence(both)
    assert (h.value, h.passed) == ("2 topic(s)", False)
    assert h.detail == "/vega/ins starts at seq 1; /vega/diagnostics missing"
    # a missing topic does not end the check of the topics after it
    h = bagcheck._check_sequence(_edit(_without(bag, INS), CMD, seq=cmd))
    assert h.detail == "/vega/ins missing; /vega/tvc_cmd seq 9 → 11 (gap) at 20.224 s; 1 in all"
    # a topic with no messages has nothing to check, and the others still are
    h = bagcheck._check_sequence(_edit(_take(bag, INS, 0), CMD, seq=cmd))
    assert h.detail == "/vega/tvc_cmd seq 9 → 11 (gap) at 20.224 s; 1 in all"


def test_lockstep_problems_by_hand(small):
    _, _, bag = small
    ctx_timing = TIMING
    ok = bagcheck._check_lockstep(bag, ctx_timing)
    assert ok.passed and ok.value == "ok"
    log = bag[INS].log_time_ns.copy()
    log[4] += MS
    h = bagcheck._check_lockstep(_edit(bag, INS, log_time_ns=log), ctx_timing)
    assert h == bagcheck.HealthResult(
        "lockstep", "no lockstep stalls", "1 problem(s)", "+10 ms/frame, +20 ms/cmd", False,
        "/vega/ins log time 20.053 s ≠ stamp 20.052 s")
    # a stall: truth stamp 30 repeats stamp 29 (log time too)
    st = bag[TRUTH]["stamp_ns"].copy()
    st[30] = st[29]
    h = bagcheck._check_lockstep(_edit(bag, TRUTH, log_time_ns=st, stamp_ns=st), ctx_timing)
    assert h.detail == "/vega/truth stamp stalled at 20.290 s (expected +10 ms); 2 in all"
    st = bag[TRUTH]["stamp_ns"].copy()
    st[30] = st[29] - MS                                   # backwards: also a stall
    h = bagcheck._check_lockstep(_edit(bag, TRUTH, log_time_ns=st, stamp_ns=st), ctx_timing)
    assert h.detail.startswith("/vega/truth stamp stalled at 20.290 s")
    # an advance: commands 5… one ms later (sample stamps too: the latency stays 24 ms)
    st, sa = bag[CMD]["stamp_ns"].copy(), bag[CMD]["sample_stamp_ns"].copy()
    st[5:] += MS
    sa[5:] += MS
    h = bagcheck._check_lockstep(_edit(bag, CMD, log_time_ns=st, stamp_ns=st,
                                       sample_stamp_ns=sa), ctx_timing)
    assert h.detail == "/vega/tvc_cmd stamp advanced 21 ms at 20.104 s (expected +20 ms); " \
                       "1 in all"
    # the actuator's frame period is 10 ms too
    st = bag[ACT]["stamp_ns"].copy()
    st[7:] += 2 * MS
    h = bagcheck._check_lockstep(_edit(bag, ACT, log_time_ns=st, stamp_ns=st), ctx_timing)
    assert h.detail == "/vega/actuator stamp advanced 12 ms at 20.070 s (expected +10 ms); " \
                       "1 in all"
    # latencies: INS 12 ms, commands 12 + 12 ms
    sa = bag[INS]["sample_stamp_ns"].copy()
    sa[3] -= MS
    h = bagcheck._check_lockstep(_edit(bag, INS, sample_stamp_ns=sa), ctx_timing)
    assert h.detail == "/vega/ins stamp − sample_stamp = 13 ms at 20.042 s (expected 12 ms)"
    sa = bag[CMD]["sample_stamp_ns"].copy()
    sa[2] += MS
    h = bagcheck._check_lockstep(_edit(bag, CMD, sample_stamp_ns=sa), ctx_timing)
    assert h.detail == "/vega/tvc_cmd stamp − sample_stamp = 23 ms at 20.064 s " \
                       "(expected 24 ms)"
    # several: counted, joined in topic order
    log = bag[INS].log_time_ns.copy()
    log[4] += MS
    sa = bag[INS]["sample_stamp_ns"].copy()
    sa[3] -= MS
    h = bagcheck._check_lockstep(_edit(bag, INS, log_time_ns=log, sample_stamp_ns=sa),
                                 ctx_timing)
    assert h.value == "2 problem(s)" and h.detail == (
        "/vega/ins log time 20.053 s ≠ stamp 20.052 s; "
        "/vega/ins stamp − sample_stamp = 13 ms at 20.042 s (expected 12 ms)")


def test_lockstep_edge_cases(small):
    _, _, bag = small
    # one nanosecond forward is an advance, not a stall
    st = bag[TRUTH]["stamp_ns"].copy()
    st[30] = st[29] + 1
    h = bagcheck._check_lockstep(_edit(bag, TRUTH, log_time_ns=st, stamp_ns=st), TIMING)
    assert h.detail.startswith("/vega/truth stamp advanced 1e-06 ms at 20.290 s")
    # a latency printed to 6 significant digits in ms (999 999 ns)
    sa = bag[INS]["sample_stamp_ns"].copy()
    sa[3] = bag[INS]["stamp_ns"][3] - 999_999
    h = bagcheck._check_lockstep(_edit(bag, INS, sample_stamp_ns=sa), TIMING)
    assert h.detail == "/vega/ins stamp − sample_stamp = 0.999999 ms at 20.042 s " \
                       "(expected 12 ms)"
    # a topic of one message is checked (its log time), an empty one does not end the check
    log = bag[DIAG].log_time_ns[:1] + MS
    one = _edit(_take(bag, DIAG, 1), DIAG, log_time_ns=log)
    h = bagcheck._check_lockstep(one, TIMING)
    assert h.detail == "/vega/diagnostics log time 20.025 s ≠ stamp 20.024 s"
    st = bag[ACT]["stamp_ns"].copy()
    st[7:] += 2 * MS
    h = bagcheck._check_lockstep(_edit(_take(bag, INS, 0), ACT, log_time_ns=st, stamp_ns=st),
                                 TIMING)
    assert h.detail.startswith("/vega/actuator stamp advanced 12 ms at 20.070 s")
    assert list(bag.topics).index(INS) < list(bag.topics).index(ACT)


def test_lockstep_other_timing_and_clock(small):
    """The limits come from the timing given; /clock (100 ms apart) has no period check, but
    its log time must still be its stamp; diagnostics have no latency check."""
    _, _, bag = small
    slow = dataclasses.replace(TIMING, frame_ms=20, controller_period_ms=40)
    h = bagcheck._check_lockstep(bag, slow)
    assert h.limit == "+20 ms/frame, +40 ms/cmd" and not h.passed
    assert h.detail.startswith("/vega/truth stamp advanced 10 ms at 20.000 s (expected +20 ms)")
    log = bag[CLOCK].log_time_ns.copy()
    log[2] += MS
    clock_first = _edit(bag, CLOCK, log_time_ns=log)
    clock_first = dataclasses.replace(clock_first, topics={
        CLOCK: clock_first[CLOCK], **{k: v for k, v in clock_first.topics.items()
                                      if k != CLOCK}})
    ins = bag[INS]["sample_stamp_ns"].copy()
    ins[0] -= MS
    h = bagcheck._check_lockstep(_edit(clock_first, INS, sample_stamp_ns=ins), TIMING)
    assert h.detail == ("/clock log time 20.201 s ≠ stamp 20.200 s; /vega/ins stamp − "
                        "sample_stamp = 13 ms at 20.012 s (expected 12 ms)")
    assert bagcheck._check_lockstep(_take(bag, INS, 0), TIMING).passed


def test_coverage_problems_by_hand(small):
    _, _, bag = small
    ctx = bagcheck.run_context(bag)
    h = bagcheck._check_coverage(_take(bag, INS, 49), ctx)
    assert h == bagcheck.HealthResult(
        "coverage", "run complete", "20.000 … 20.500 s", "20.000 … 20.500 s", False,
        "/vega/ins: 49 messages, a complete run has 50; "
        "/vega/ins spans 20.012 s … 20.492 s, expected 20.012 s … 20.502 s")
    h = bagcheck._check_coverage(_take(bag, TRUTH, 40), ctx)
    assert h.value == "20.000 … 20.390 s" and h.detail == (
        "/vega/truth: 40 messages, a complete run has 51; "
        "/vega/truth spans 20.000 s … 20.390 s, expected 20.000 s … 20.500 s")
    # the right count but shifted by one frame: only the span
    st = bag[INS]["stamp_ns"] + 10 * MS
    h = bagcheck._check_coverage(_edit(bag, INS, stamp_ns=st), ctx)
    assert h.detail == "/vega/ins spans 20.022 s … 20.512 s, expected 20.012 s … 20.502 s"
    st = bag[CMD]["stamp_ns"].copy()
    st[-1] += MS
    h = bagcheck._check_coverage(_edit(bag, CMD, stamp_ns=st), ctx)
    assert h.detail == "/vega/tvc_cmd spans 20.024 s … 20.505 s, expected 20.024 s … 20.504 s"
    st = bag[DIAG]["stamp_ns"].copy()
    st[0] -= MS
    h = bagcheck._check_coverage(_edit(bag, DIAG, stamp_ns=st), ctx)
    assert h.detail == ("/vega/diagnostics spans 20.023 s … 20.504 s, expected 20.024 s … "
                        "20.504 s")
    st = bag[ACT]["stamp_ns"].copy()
    st[0] -= 10 * MS
    h = bagcheck._check_coverage(_edit(bag, ACT, stamp_ns=st), ctx)
    assert h.detail == "/vega/actuator spans 20.000 s … 20.500 s, expected 20.010 s … 20.500 s"
    h = bagcheck._check_coverage(_without(bag, DIAG), ctx)
    assert h.detail == "/vega/diagnostics: 0 messages, a complete run has 25"
    h = bagcheck._check_coverage(_take(_take(bag, DIAG, 0), INS, 49), ctx)
    assert h.detail.startswith("/vega/ins: 49 messages, a complete run has 50; /vega/ins spans")
    assert h.detail.endswith("; /vega/diagnostics: 0 messages, a complete run has 25")


def test_coverage_goes_on_after_an_empty_topic(small):
    _, _, bag = small
    ctx = bagcheck.run_context(bag)
    st = bag[CMD]["stamp_ns"].copy()
    st[-1] += MS
    h = bagcheck._check_coverage(_edit(_take(bag, INS, 0), CMD, stamp_ns=st), ctx)
    assert h.detail == ("/vega/ins: 0 messages, a complete run has 50; /vega/tvc_cmd spans "
                        "20.024 s … 20.505 s, expected 20.024 s … 20.504 s")


def test_coverage_value_is_the_truth_span_in_ms(small):
    """Truth stamps 20 000 500 010 and 20 500 500 010 ns print as 20.001 … 20.501 s."""
    _, _, bag = small
    st = bag[TRUTH]["stamp_ns"].copy()
    st[0], st[-1] = 20_000_500_010, 20_500_500_010
    h = bagcheck._check_coverage(_edit(bag, TRUTH, stamp_ns=st), bagcheck.run_context(bag))
    assert h.value == "20.001 … 20.501 s"


def test_coverage_of_the_clock(small):
    _, _, bag = small
    ctx = bagcheck.run_context(bag)
    clock = bag[CLOCK]
    five = dataclasses.replace(clock, log_time_ns=clock.log_time_ns[:5],
                               columns={k: v[:5] for k, v in clock.columns.items()})
    want = "/clock: 5 ticks, not the 6 of the schedule (every 10 frames and t_end)"
    h = bagcheck._check_coverage(dataclasses.replace(bag, topics={**bag.topics, CLOCK: five}),
                                 ctx)
    assert h.detail == want and not h.passed
    st = clock["stamp_ns"].copy()
    st[3] += 10 * MS
    h = bagcheck._check_coverage(_edit(bag, CLOCK, stamp_ns=st), ctx)
    assert h.detail == "/clock: 6 ticks, not the 6 of the schedule (every 10 frames and t_end)"
    h = bagcheck._check_coverage(_without(bag, CLOCK), ctx)
    assert h.detail == "/clock: 0 ticks, not the 6 of the schedule (every 10 frames and t_end)"


def test_coverage_without_a_span_or_without_command_samples(small):
    _, _, bag = small
    ctx = bagcheck.RunContext(None, TIMING, None, 0.0)
    assert bagcheck._check_coverage(bag, ctx) == bagcheck.HealthResult(
        "coverage", "run complete", "unknown", "scenario span", False,
        "no scenario in the metadata: span unknown")
    # a 10 ms span starting off the controller period: no command is due
    info = RunInfo("thesis", 1, 20010, 20020, TIMING)
    assert len(info.command_samples()) == 0
    cut = bag
    for name in (CMD, DIAG):
        cut = _take(cut, name, 0)
    h = bagcheck._check_coverage(cut, bagcheck.RunContext(None, TIMING, info, 0.0))
    assert "/vega/tvc_cmd" not in h.detail and "/vega/diagnostics" not in h.detail
    assert h.detail.startswith("/vega/truth: 51 messages, a complete run has 2")


def test_compute_time_by_hand():
    t_ms = np.arange(200, dtype=np.int64) * 20 + 20024
    ct = np.full(200, 1e-4)
    ct[7] = 0.0125
    h = bagcheck._check_compute_time(ct, t_ms, TIMING)
    # 1 of 200 over, 2 allowed (1 %); p99 of 199 × 100 µs and one 12.5 ms is 100 µs
    assert h == bagcheck.HealthResult(
        "compute_time", "controller compute time", "max 12.5 ms", "≤ 12 ms for ≥ 99 %", True,
        "1 of 200 command(s) over budget (allowed 2), first at 20.164 s (12.5 ms); "
        "median 100 µs, p99 100 µs, max 12500 µs", 0.012 - 1e-4)
    ct[[3, 9]] = 0.013
    h = bagcheck._check_compute_time(ct, t_ms, TIMING)
    assert not h.passed and h.detail.startswith(
        "3 of 200 command(s) over budget (allowed 2), first at 20.084 s (13 ms); ")
    ct[3] = 0.012                                          # exactly the budget: not over
    h = bagcheck._check_compute_time(ct, t_ms, TIMING)
    assert h.passed and h.detail.startswith("2 of 200 command(s) over budget (allowed 2), "
                                            "first at 20.164 s")


def test_compute_time_percentiles_by_hand():
    """1 … 100 µs: median 50.5 µs, p99 (linear) 99.01 µs, margin 12 ms − 99.01 µs."""
    ct = np.arange(1, 101) * 1e-6
    h = bagcheck._check_compute_time(ct, np.zeros(100, np.int64), TIMING)
    assert h.detail == "median 50 µs, p99 99 µs, max 100 µs" and h.passed
    assert h.margin == pytest.approx(0.012 - 99.01e-6, rel=1e-12, abs=0)
    assert h.value == "max 0.1 ms"
    # 100 commands allow 1 over, 99 commands none
    ct = np.full(100, 1e-4)
    ct[50] = 0.02
    assert bagcheck._check_compute_time(ct, np.zeros(100, np.int64), TIMING).passed
    assert not bagcheck._check_compute_time(ct[1:], np.zeros(99, np.int64), TIMING).passed
    slow = dataclasses.replace(TIMING, computing_latency_ms=30)
    h = bagcheck._check_compute_time(np.full(10, 0.025), np.zeros(10, np.int64), slow)
    assert h.passed and h.limit == "≤ 30 ms for ≥ 99 %"
    assert h.margin == pytest.approx(0.005, rel=1e-12, abs=0)


def test_compute_time_rounding_by_hand():
    """1000.4996 µs prints as 1000 µs (×1.000001 would give 1001); an overrun of 12.449 ms
    as 12.4 ms (×1.001 would give 12.5)."""
    ct = np.full(10, 1000.4996e-6)
    h = bagcheck._check_compute_time(ct, np.zeros(10, np.int64), TIMING)
    assert h.detail == "median 1000 µs, p99 1000 µs, max 1000 µs"
    ct = np.full(200, 1e-4)
    ct[0] = 0.012449
    h = bagcheck._check_compute_time(ct, np.full(200, 20_024, np.int64), TIMING)
    assert h.detail.startswith("1 of 200 command(s) over budget (allowed 2), first at "
                               "20.024 s (12.4 ms); ")


def test_compute_time_missing_or_not_finite():
    h = bagcheck._check_compute_time(np.zeros(0), np.zeros(0, np.int64), TIMING)
    assert h == bagcheck.HealthResult("compute_time", "controller compute time",
                                      "no diagnostics", "≤ 12 ms", False,
                                      "no /vega/diagnostics messages")
    ct = np.full(200, 1e-4)
    ct[4] = math.nan
    h = bagcheck._check_compute_time(ct, np.arange(200, dtype=np.int64) * 20, TIMING)
    assert not h.passed and h.value == "max inf ms" and h.margin == -math.inf
    assert h.detail == ("1 of 200 command(s) over budget (allowed 2), first at 0.080 s "
                        "(nan ms); median 100 µs, p99 inf µs, max inf µs")
    h = bagcheck._check_compute_time(np.array([math.nan]), np.zeros(1, np.int64), TIMING)
    assert not h.passed and h.detail == ("1 of 1 command(s) over budget (allowed 0), first "
                                         "at 0.000 s (nan ms); ")


# ----------------------------------------------------------------------------- the verdict
def test_verdict_of_the_complete_bag(small):
    run, path, bag = small
    check = bagcheck.check_run_bag(bag)
    assert check.passed and check.exit_code == 0 and check.failures == []
    assert check.status_counts() == {"OK": 25}
    assert check.bag == str(path) and check.metadata == bag.metadata
    assert np.array_equal(check.compute_time_s, np.full(25, 5e-5))
    lines = check.table().splitlines()
    assert lines[0] == (f"bag {path}: scenario thesis, seed {run.result.seed}, git test")
    assert lines[1] == "" and lines[-2] == "" and lines[-1] == "verdict: PASS"
    assert lines[-3] == "controller status: OK 25"
    # the health table: columns as wide as their widest cell (23, 17, 24, 4), two spaces apart
    def row(*cells):
        return "  ".join(c.ljust(w) for c, w in zip(cells, (23, 17, 24, 4, 0))).rstrip()

    head = lines.index(next(x for x in lines if x.startswith("health check")))
    assert lines[head - 1] == ""
    assert lines[head:head + 7] == [
        row("health check", "value", "limit", "pass", "detail"),
        row("metadata", "complete", "run metadata + scenario", "yes", ""),
        row("no NaN/inf", "0", "0", "yes", ""),
        row("no message gaps", "ok", "seq +1", "yes", ""),
        row("no lockstep stalls", "ok", "+10 ms/frame, +20 ms/cmd", "yes", ""),
        row("run complete", "20.000 … 20.500 s", "20.000 … 20.500 s", "yes", ""),
        row("controller compute time", "max 0.05 ms", "≤ 12 ms for ≥ 99 %", "yes",
            "median 50 µs, p99 50 µs, max 50 µs")]
    assert lines[head + 1] == "metadata                 complete           " \
                              "run metadata + scenario   yes"
    assert lines[head + 7] == lines[-3]
    assert check.requirements.table() in check.table()
    assert check.context == bagcheck.run_context(bag) and check.context.t_start_ms == 20000
    again = bagcheck.check_bag(path)
    assert again.to_dict() == check.to_dict()


def test_failures_and_verdict_text(small):
    _, _, bag = small
    drift = bag[TRUTH]["drift_m"].copy()
    drift[20] = -612.5                                     # 20.200 s
    pitch = bag[INS]["pitch_rad"].copy()
    pitch[5] = math.nan
    check = bagcheck.check_run_bag(_edit(_edit(bag, TRUTH, drift_m=drift), INS,
                                         pitch_rad=pitch))
    assert not check.passed and check.exit_code == 1
    assert check.failures == [
        "Lateral control performance z: -612.5 m at 20.200 s exceeds its bound 500 m by "
        "112.5 m",
        "no NaN/inf: /vega/ins pitch_rad not finite at 20.062 s"]
    table = check.table().splitlines()
    assert table[-1] == "verdict: FAIL: " + "; ".join(check.failures)
    row = next(x for x in table if x.startswith("no NaN/inf "))
    assert row.endswith("  NO    /vega/ins pitch_rad not finite at 20.062 s")
    assert next(x for x in table if x.startswith("metadata ")).endswith(" yes")
    d = check.to_dict()
    assert d["passed"] is False and d["exit_code"] == 1 and d["failures"] == check.failures
    # only a health check failed: the requirements still pass
    check = bagcheck.check_run_bag(_edit(bag, INS, pitch_rad=pitch))
    assert check.requirements.passed and not check.passed and check.exit_code == 1
    assert check.failures == ["no NaN/inf: /vega/ins pitch_rad not finite at 20.062 s"]


def test_title_without_run_metadata(small):
    _, path, bag = small
    check = bagcheck.check_run_bag(_meta(bag, META_SCENARIO=None, META_SEED=None,
                                         META_GIT_REVISION=None))
    assert check.table().splitlines()[0] == f"bag {path}: scenario ?, seed ?, git ?"


def test_log_times_are_printed_rounded_to_the_millisecond(small):
    """20 000 500 010 ns is 20.00050001 s: printed 20.001 s (a divisor off by one part in 1e9
    would give 20.000)."""
    _, _, bag = small
    pitch = bag[INS]["pitch_rad"].copy()
    pitch[0] = math.nan
    log = bag[INS].log_time_ns.copy()
    log[0] = 20_000_500_010
    h = bagcheck._check_finite(_edit(bag, INS, log_time_ns=log, pitch_rad=pitch))
    assert h.detail == "/vega/ins pitch_rad not finite at 20.001 s"


def test_a_failed_informational_line_is_not_a_failure(small, tmp_path):
    import yaml

    from vega_sim.requirements import default_requirements_path, load_requirements

    _, _, bag = small
    tree = yaml.safe_load(default_requirements_path().read_text())
    tree["q_alpha_objective"]["value"] = [v / 1000.0 for v in tree["q_alpha_objective"]["value"]]
    req = tmp_path / "req.yaml"
    req.write_text(yaml.safe_dump(tree))
    check = bagcheck.check_run_bag(bag, load_requirements(req))
    (info,) = check.requirements.informational
    assert not info.passed and not info.gating
    assert check.passed and check.failures == []


def test_status_counts_by_name(small):
    _, _, bag = small
    status = bag[CMD]["status"].copy()
    status[[1, 2, 3]] = 4                                  # LIMITED
    status[5] = 2                                          # VELOCITY_CLAMPED
    status[6] = 99                                         # not a named status
    check = bagcheck.check_run_bag(_edit(bag, CMD, status=status))
    assert check.status_counts() == {"OK": 20, "VELOCITY_CLAMPED": 1, "LIMITED": 3, "99": 1}
    assert "controller status: OK 20, VELOCITY_CLAMPED 1, LIMITED 3, 99 1" in check.table()
    check = bagcheck.check_run_bag(_take(_take(bag, CMD, 0), DIAG, 0))
    assert check.status_counts() == {}
    assert "controller status: no commands" in check.table()
    assert check.compute_time_s.size == 0
    assert not check.passed and "controller compute time: no /vega/diagnostics messages" in \
        check.failures


def test_compute_time_from_the_bag(small):
    """Without the diagnostics topic: "no diagnostics"; an overrun is dated by its message's
    stamp in whole ms (20.0249 s → 20.024 s)."""
    _, _, bag = small
    h = {x.key: x for x in bagcheck.check_run_bag(_without(bag, DIAG)).health}
    assert (h["compute_time"].value, h["compute_time"].passed) == ("no diagnostics", False)
    st = bag[DIAG]["stamp_ns"].copy()
    st[0] = 20_024_900_000
    ct = bag[DIAG]["compute_time_s"].copy()
    ct[0] = 0.02
    h = {x.key: x for x in bagcheck.check_run_bag(_edit(bag, DIAG, stamp_ns=st,
                                                         compute_time_s=ct)).health}
    assert h["compute_time"].detail.startswith("1 of 25 command(s) over budget (allowed 0), "
                                               "first at 20.024 s (20 ms); ")


def test_to_dict_layout_and_numbers(small, tmp_path):
    _, _, bag = small
    check = bagcheck.check_run_bag(bag)
    d = check.to_dict()
    assert list(d) == ["bag", "passed", "exit_code", "failures", "requirements",
                       "informational", "q_alpha_sensitivity", "thesis_definitions", "health",
                       "controller_status", "metadata"]
    assert d["bag"] == check.bag and d["passed"] is True and d["exit_code"] == 0
    assert d["controller_status"] == {"OK": 25} and d["metadata"] == dict(bag.metadata)
    rep = check.requirements
    for rows, results in ((d["requirements"], rep.results), (d["informational"],
                                                              rep.informational)):
        assert len(rows) == len(results)
        for row, r in zip(rows, results):
            s = r.display_scale
            assert list(row) == [
                "key", "requirement", "metric", "value", "bound", "margin", "unit", "passed",
                "gating", "time_s", "peak_value", "peak_time_s", "peak_bound", "display_unit",
                "value_display", "bound_display", "margin_display", "peak_value_display",
                "thesis_table_5_1_display"]
            assert (row["key"], row["requirement"], row["metric"], row["unit"],
                    row["passed"], row["gating"], row["display_unit"]) == (
                r.key, r.requirement, r.metric, r.unit, r.passed, r.gating, r.display_unit)
            for k, v in (("value", r.value), ("bound", r.bound), ("margin", r.margin),
                         ("time_s", r.time_s), ("peak_value", r.peak_value),
                         ("peak_time_s", r.peak_time_s), ("peak_bound", r.peak_bound),
                         ("value_display", r.value * s), ("bound_display", r.bound * s),
                         ("margin_display", r.margin * s),
                         ("peak_value_display", r.peak_value * s)):
                want = None if v is None else (float(v) if math.isfinite(v) else str(float(v)))
                assert row[k] == want, (r.key, k)
            assert row["thesis_table_5_1_display"] == (
                None if r.thesis is None else float(r.thesis.value * s))
    drift = next(r for r in d["requirements"] if r["key"] == "drift")
    assert drift["unit"] == "m" and drift["bound"] == 500.0 and drift["bound_display"] == 500.0
    qa = next(r for r in d["requirements"] if r["key"] == "q_alpha")
    assert math.isclose(qa["value_display"], math.degrees(qa["value"]), rel_tol=1e-15)
    flip = rep.q_alpha_flip
    sens = d["q_alpha_sensitivity"]
    assert list(sens) == ["alpha_max_deg", "mach_min", "floor_pa_deg", "alpha_flip_deg",
                          "alpha_flip_time_s", "alpha_flip_mach", "floor_flip_pa_deg",
                          "floor_flip_time_s", "alpha_flip_tied_deg", "mach_min_flip",
                          "passed"]
    deg = 180.0 / math.pi
    for k, v in (("alpha_max_deg", flip.alpha_max_rad * deg), ("mach_min", flip.mach_min),
                 ("floor_pa_deg", flip.floor_pa_rad * deg),
                 ("alpha_flip_deg", flip.alpha_flip_rad * deg),
                 ("alpha_flip_time_s", flip.alpha_flip_time_s),
                 ("alpha_flip_mach", flip.alpha_flip_mach),
                 ("floor_flip_pa_deg", flip.floor_flip_pa_rad * deg),
                 ("floor_flip_time_s", flip.floor_flip_time_s),
                 ("alpha_flip_tied_deg", flip.alpha_flip_tied_rad * deg),
                 ("mach_min_flip", flip.mach_min_flip)):
        got = sens[k]
        if isinstance(got, str) or v is None or not math.isfinite(v):
            assert got == (None if v is None else str(float(v))), k
        else:
            assert got == pytest.approx(v, rel=1e-14, abs=0), k
    assert sens["alpha_max_deg"] == pytest.approx(4.0, rel=1e-14) and sens["passed"] is True
    assert d["thesis_definitions"] == {
        "command_peak_rad": float(rep.command_peak_rad),
        "command_signed_integral_rad_s": float(rep.command_signed_integral_rad_s)}
    assert d["health"][0] == {"key": "metadata", "check": "metadata", "value": "complete",
                              "limit": "run metadata + scenario", "passed": True,
                              "detail": "", "margin": None}
    assert d["health"][5]["margin"] == 0.012 - 5e-5
    # the file: indented JSON, non-ASCII kept, one newline at the end
    out = check.write_json(tmp_path / "v.json")
    assert out == tmp_path / "v.json"
    text = out.read_text(encoding="utf-8")
    assert text.endswith("}\n") and not text.endswith("\n\n")
    assert '\n  "bag": ' in text and "≤ 12 ms" in text
    assert json.loads(text) == json.loads(json.dumps(d))
    out = check.write_json(str(tmp_path / "w.json"))
    assert out.read_text(encoding="utf-8") == text


def test_json_file_is_utf8_whatever_the_locale(small, tmp_path):
    """Under the C locale (ASCII) the file is still UTF-8 ("≤" in the limits)."""
    import locale

    _, _, bag = small
    check = bagcheck.check_run_bag(bag)
    old = locale.setlocale(locale.LC_CTYPE)
    try:
        locale.setlocale(locale.LC_CTYPE, "C")
        out = check.write_json(tmp_path / "c.json")
    finally:
        locale.setlocale(locale.LC_CTYPE, old)
    assert "≤ 12 ms".encode() in out.read_bytes()


def test_to_dict_without_a_sensitivity_line(small):
    _, _, bag = small
    check = bagcheck.check_run_bag(bag)
    rep = dataclasses.replace(check.requirements, q_alpha_flip=None)
    assert dataclasses.replace(check, requirements=rep).to_dict()["q_alpha_sensitivity"] is None


def test_num_for_json():
    assert bagcheck._num(None) is None
    assert bagcheck._num(math.nan) == "nan" and bagcheck._num(-math.inf) == "-inf"
    assert bagcheck._num(math.inf) == "inf"
    x = bagcheck._num(np.float32(1.5))
    assert x == 1.5 and type(x) is float
    assert type(bagcheck._num(3)) is float and bagcheck._num(3) == 3.0


def test_check_bag_reads_the_bag(small):
    _, path, bag = small
    a, b = bagcheck.check_bag(path), bagcheck.check_run_bag(bag)
    assert a.health == b.health and a.bag == b.bag == str(path)
    with pytest.raises(bagio.BagError, match="no such file"):
        bagcheck.check_bag(path.parent / "missing")
