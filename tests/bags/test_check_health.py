"""The run-health checks of `vega check` (vega_bags.bagcheck): metadata, no NaN/inf, no message
gaps, no lockstep stalls, run complete, controller compute time.

One short in-process flight (thesis scenario, 20.0 … 20.5 s, PD fixture table) is written to a
bag and read back once; faults are injected into the columns of that loaded bag in memory
(tests/bags/check_bag_edits.py), so each piece is exercised on its own.

Independent references: the schedule of the 0.5 s run typed out by hand from the loop timing
(vehicle.yaml: 10 ms frames, 20 ms controller period, 12 ms sensor and computing latency,
15 ms actuator latency, 1 ms physics step): truth 51 messages 20.000 … 20.500 s, INS 50 at
sample + 12 ms, actuator 50 frames stamped 20.010 … 20.500 s of 10 samples each, 25 commands
sampled 20.000 … 20.480 s and stamped 24 ms later, /clock at 20.0, 20.1, … 20.5 s; each
check's detail text typed out by hand, values at the rounding edges of the printed figures
included; percentiles and medians of small hand arrays against the compute-time budget (the
computing latency, 12 ms, for at least 99 % of the commands).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from check_bag_edits import (ACT, CLOCK, CMD, DIAG, INS, MS, TIMING, TRUTH, short_run_bag, _edit,
                             _stamps_ms, _take, _without)
from vega_bags import bagcheck
from vega_bus.schedule import RunInfo


@pytest.fixture(scope="module")
def small():
    """(the in-process run, its bag directory, the loaded bag); flown once per set of inputs
    (tests/bags/cached_bags.py)."""
    return short_run_bag()


# --------------------------------------------------------------------------------- the fixture bag
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


# ----------------------------------------------------------------------------------- health checks
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
