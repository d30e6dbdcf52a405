"""What `vega check` rebuilds from a bag (vega_bags.bagcheck): the run context from the run
metadata, and the run itself.

One short in-process flight (thesis scenario, 20.0 … 20.5 s, PD fixture table) is written to a
bag and read back once; faults are injected into the columns of that loaded bag in memory
(tests/bags/check_bag_edits.py), so each piece is exercised on its own.

The run context: scenario, seed (the metadata's if a non-negative integer, else the
scenario's), loop timing, start time and initial nozzle angle β(t_start), every missing key
named. The run: the bag gives back the in-process run's own arrays bit for bit; the actuator
sample instants (sample j of k in a frame stamped S lies at S − (k−1−j)·dt) and the held
command (a command stamped S acts from S + 15 ms, the actuator latency, on the physics step
ending at t when t − dt ≥ S + 15 ms; before the first one β(t_start)) against hand values and a
plain loop, times in whole ms; a bag without truth or actuator messages is a bag error.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from check_bag_edits import (ACT, CMD, INS, MS, TIMING, TRUTH, short_run_bag, _edit, _meta, _take,
                             _without)
from vega_bags import bagcheck, bagio
from vega_bus.schedule import RunInfo
from vega_bus.timing import LoopTiming


@pytest.fixture(scope="module")
def small():
    """(the in-process run, its bag directory, the loaded bag); flown once per set of inputs
    (tests/bags/cached_bags.py)."""
    return short_run_bag()


# ------------------------------------------------------------------------------------- run_context
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


# ----------------------------------------------------------------------------------------- the run
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
