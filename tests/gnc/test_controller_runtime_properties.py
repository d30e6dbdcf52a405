"""Property tests of the on-board controller runtime (hypothesis): for ANY input sequence the
command is finite, within ±6.5°, the state stays finite, and the status says what happened.

Inputs mix ordinary measurements with faults the loop must survive: huge finite values
(1e200, 1.7e308), NaN and ±inf in every field, invalid flags, stamps that repeat, go back,
jump ahead or lie in the future, stale arrivals and velocities outside the grid. The oracle
below re-derives each step's status from the documented rules (controller_runtime module
docstring) independently of the runtime's code; it does not compute the control law itself,
only what the status implies about the command.

Runs derandomized (a fixed example sequence), so CI is reproducible.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fixture_tables import write_gain_table
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_LIMITED, STATUS_OK,
                                         STATUS_SAFE_ZERO, STATUS_VELOCITY_CLAMPED,
                                         ControllerRuntime, Measurement, RuntimeLimits)
from vega_gnc.controller_table import default_table_path, load_controller_table

LIMITS = RuntimeLimits()
LIM = LIMITS.limit_rad
SETTINGS = settings(derandomize=True, deadline=None, max_examples=150,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow, HealthCheck.data_too_large])

_faults = st.sampled_from([math.nan, math.inf, -math.inf, 1e200, -1e200, 1.7e308, -1.7e308])
_good = st.fixed_dictionaries({
    "dt_ms": st.just(20),                                   # stamp increment
    "age_ms": st.sampled_from([0, 12, 12, 32]),             # arrival − stamp
    "pitch": st.floats(-0.5, 0.5, allow_nan=False),
    "rate": st.floats(-0.5, 0.5, allow_nan=False),
    "drift": st.floats(-500.0, 500.0, allow_nan=False),
    "drift_rate": st.floats(-50.0, 50.0, allow_nan=False),
    "velocity": st.floats(-5.0, 2500.0, allow_nan=False),
    "valid": st.just(True),
})
_fault_kinds = st.one_of(
    st.tuples(st.sampled_from(["pitch", "rate", "drift", "drift_rate", "velocity"]), _faults),
    st.tuples(st.just("valid"), st.just(False)),
    st.tuples(st.just("dt_ms"), st.sampled_from([0, -20, 40, 260, 1000])),
    st.tuples(st.just("age_ms"), st.sampled_from([33, 50, 400, -1, -1000])),
)


@st.composite
def _step(draw):
    """Mostly a good measurement on the 20 ms grid; sometimes one field or time is broken."""
    s = dict(draw(_good))
    if draw(st.integers(0, 9)) < 3:
        for key, value in draw(st.lists(_fault_kinds, min_size=1, max_size=2)):
            s[key] = value
    return s


def _plausible(s):
    limits = (LIMITS.max_abs_pitch_rad, LIMITS.max_abs_pitch_rate_radps,
              LIMITS.max_abs_drift_m, LIMITS.max_abs_drift_rate_mps, LIMITS.max_velocity_mps)
    values = (s["pitch"], s["rate"], s["drift"], s["drift_rate"], s["velocity"])
    return all(abs(x) <= b for x, b in zip(values, limits))


def _check_sequence(table, steps):
    """Fly ``steps`` through a fresh runtime and check every command against the rules."""
    rt = ControllerRuntime(table, LIMITS)
    grid = (float(table.grid_v_mps[0]), float(table.grid_v_mps[-1]))
    stamp_ms, newest_ms, used_ms, last_u = 10_000, None, None, None
    for s in steps:
        stamp_ms += s["dt_ms"]
        now_ms = stamp_ms + s["age_ms"]
        m = Measurement(stamp_ms / 1000.0, s["pitch"], s["rate"], s["drift"], s["drift_rate"],
                        s["velocity"], s["valid"])
        cmd = rt.step(m, now_s=now_ms / 1000.0)
        u = cmd.deflection_cmd_rad
        # the invariants every command keeps
        assert math.isfinite(u) and abs(u) <= LIM, (s, cmd)
        assert np.all(np.isfinite(rt.state)), (s, cmd)
        # the oracle: was this measurement usable?
        newer = newest_ms is None or stamp_ms > newest_ms
        usable = (s["valid"] and newer and 0 <= now_ms - stamp_ms <= 32 and _plausible(s))
        if newer and stamp_ms <= now_ms:
            newest_ms = stamp_ms
        if not usable:
            if used_ms is not None and now_ms - used_ms <= 200:
                assert cmd.status == STATUS_HOLD_LAST and u == last_u, (s, cmd)
            else:
                assert cmd.status == STATUS_SAFE_ZERO and u == 0.0, (s, cmd)
                used_ms, last_u = None, None
            continue
        # a usable measurement: computed (or, only on a gain overflow, zeroed)
        assert cmd.status in (STATUS_OK, STATUS_VELOCITY_CLAMPED, STATUS_LIMITED,
                              STATUS_SAFE_ZERO), (s, cmd)
        if cmd.status == STATUS_SAFE_ZERO:
            assert u == 0.0
            used_ms, last_u = None, None
            continue
        inside = grid[0] <= s["velocity"] <= grid[1]
        if cmd.status == STATUS_LIMITED:
            assert abs(u) == LIM
        else:
            assert abs(u) <= LIM
            assert (cmd.status == STATUS_OK) == inside, (s, cmd)
        assert cmd.scheduling_velocity_mps == min(max(s["velocity"], grid[0]), grid[1])
        used_ms, last_u = now_ms, u


@pytest.fixture(scope="module", params=["default", "lpv"])
def flight_table(request, lpv_table):
    """The shipped tables: the flown structured one (8 states) and the LPV one (large gains,
    19 states: an overflow is possible with it)."""
    return load_controller_table(default_table_path()) if request.param == "default" else lpv_table


@pytest.fixture(scope="module")
def lpv_table():
    return load_controller_table(default_table_path().with_name("lpv_controller.npz"))


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """β_cmd = 0.5·θ_INS: saturates for |θ| > 13° (0.227 rad)."""
    return write_gain_table(tmp_path_factory.mktemp("prop") / "gain.npz")


@pytest.mark.slow
@SETTINGS
@given(steps=st.lists(_step(), min_size=1, max_size=40))
def test_any_input_sequence_flight_table(flight_table, steps):
    _check_sequence(flight_table, steps)


@pytest.mark.slow
@SETTINGS
@given(steps=st.lists(_step(), min_size=1, max_size=40))
def test_any_input_sequence_gain_table(gain_table, steps):
    _check_sequence(gain_table, steps)


def test_the_oracle_rejects_the_old_defect(lpv_table):
    """The property above fails on the defect it guards against: a runtime that uses a huge
    pitch (no plausibility bound) overflows the flight table's state (checked here directly:
    the bound is what keeps the state finite)."""
    unbounded = RuntimeLimits(max_abs_pitch_rad=math.inf)
    rt = ControllerRuntime(lpv_table, unbounded)
    rt.step(Measurement(0.0, 0.001, 0.0, 0.0, 0.0, 300.0))
    with np.errstate(over="ignore", invalid="ignore"):
        cmd = rt.step(Measurement(0.02, 1.7e308, 0.0, 0.0, 0.0, 300.0))
    # without the bound only the finiteness check is left: it must zero, never emit NaN
    assert cmd.status == STATUS_SAFE_ZERO and cmd.deflection_cmd_rad == 0.0
    assert np.all(np.isfinite(rt.state))
