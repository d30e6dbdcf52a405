"""What the controller runtime commands and reports when it cannot use the law's command.

A held (HOLD_LAST) or zero (SAFE_ZERO) command reports the measured scheduling velocity
[m/s] (NaN when that is not finite); values exactly at their plausibility bounds
(RuntimeLimits: |θ̇| ≤ 10 rad/s, |v| ≤ 1e4 m/s, inclusive) are used, not held; a table whose
gains overflow gives command 0 with the scheduling velocity of its grid and a zeroed state.
Expected numbers by hand for the static-gain table β_cmd = 0.5·θ_INS (tests/fixture_tables.py,
measurement sign +1; documented law in vega_gnc/controller_runtime.py).
"""

import math

import numpy as np
import pytest

from fixture_tables import write_gain_table
from vega_loops.export import write_controller_table
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_OK, STATUS_SAFE_ZERO,
                                         ControllerRuntime, Measurement, RuntimeLimits)
from vega_gnc.controller_table import MEASUREMENT_NAMES

NAMES = list(MEASUREMENT_NAMES)


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """β_cmd = 0.5·θ_INS, grid 0..3000 m/s, measurement sign +1."""
    return write_gain_table(tmp_path_factory.mktemp("gain") / "gain.npz")


def _m(stamp, pitch=0.0, v=500.0, valid=True, rate=0.0):
    return Measurement(stamp, pitch, rate, 0.0, 0.0, v, valid)


# ------------------------------------------------- scheduling velocity of held and zero commands
def test_held_command_reports_the_measured_velocity(gain_table):
    rt = ControllerRuntime(gain_table)
    used = rt.step(_m(1.0, 0.02, v=500.0))
    held = rt.step(_m(1.02, 0.02, v=612.5, valid=False))
    assert held == (used.deflection_cmd_rad, 612.5, STATUS_HOLD_LAST)


def test_first_invalid_measurement_is_safe_zero_with_its_velocity(gain_table):
    cmd = ControllerRuntime(gain_table).step(_m(1.0, 0.02, v=612.5, valid=False))
    assert cmd == (0.0, 612.5, STATUS_SAFE_ZERO)


@pytest.mark.parametrize("v", [math.inf, -math.inf, math.nan])
def test_non_finite_velocity_is_reported_as_nan(gain_table, v):
    rt = ControllerRuntime(gain_table)
    rt.step(_m(1.0, 0.02))
    cmd = rt.step(_m(1.02, 0.02, v=v))
    assert cmd.status == STATUS_HOLD_LAST and math.isnan(cmd.scheduling_velocity_mps)


def test_non_finite_receive_time_is_safe_zero_with_nan_velocity(gain_table):
    cmd = ControllerRuntime(gain_table).step(_m(1.0, 0.02), now_s=math.nan)
    assert cmd.deflection_cmd_rad == 0.0 and cmd.status == STATUS_SAFE_ZERO
    assert math.isnan(cmd.scheduling_velocity_mps)


# ------------------------------------------------------------- plausibility bounds at the value
def test_values_exactly_at_their_plausibility_bounds_are_used(gain_table):
    """RuntimeLimits: |θ̇| ≤ 10 rad/s and |v| ≤ 1e4 m/s are plausible (bounds inclusive)."""
    unlimited = RuntimeLimits(limit_rad=1e9)
    cmd = ControllerRuntime(gain_table, unlimited).step(_m(1.0, 0.02, v=1e4, rate=10.0))
    assert cmd.status != STATUS_HOLD_LAST and cmd.status != STATUS_SAFE_ZERO
    assert cmd.deflection_cmd_rad == pytest.approx(0.01, abs=1e-15)
    cmd = ControllerRuntime(gain_table, unlimited).step(_m(1.0, 0.02, v=500.0, rate=-10.0))
    assert cmd == (pytest.approx(0.01, abs=1e-15), 500.0, STATUS_OK)
    beyond = ControllerRuntime(gain_table, unlimited).step(_m(1.0, 0.02, rate=10.000001))
    assert beyond.status == STATUS_SAFE_ZERO


# ------------------------------------------------------------------ a table whose gains overflow
@pytest.fixture(scope="module")
def overflow_table(tmp_path_factory):
    """Static gain 1e308 on every input: |u| = 4e308·|y| overflows to inf for y = 1."""
    meta = {"input_names": NAMES, "measurement_sign": 1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    A = np.full((2, 1, 1), -1.0)
    B = np.zeros((2, 1, 4))
    C = np.zeros((2, 1, 1))
    D = np.full((2, 1, 4), 1e308)
    return write_controller_table(tmp_path_factory.mktemp("ovf") / "o.npz", [100.0, 900.0],
                                  A, B, C, D, dt_s=0.02, gamma=1.0, gamma_min=1.0,
                                  rate_bounds_mps2=[5.4, 36.4], metadata=meta)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.parametrize("v, v_sched", [(250.0, 250.0), (5000.0, 900.0)])
def test_overflowing_command_is_zero_with_the_scheduling_velocity(overflow_table, v, v_sched):
    rt = ControllerRuntime(overflow_table)
    cmd = rt.step(Measurement(1.0, 1.0, 1.0, 1.0, 1.0, v))
    assert cmd == (0.0, v_sched, STATUS_SAFE_ZERO)
    assert np.all(rt.state == 0.0)
