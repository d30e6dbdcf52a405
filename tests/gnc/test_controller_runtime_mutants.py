"""Controller runtime behaviour that mutation testing (``make mutation MODULE=controller_runtime``)
found unchecked: the guidance reference and feed-forward in the control law, the scheduling
velocity reported with held / safe-zero commands, the plausibility bounds at their values, and
the command of a table whose gains overflow.

Every expected number is derived here by hand from the documented law (module docstring of
vega_gnc/controller_runtime.py): ``u = Cd x + Dd y + β_ff(t)``, ``y = sign·(meas − ref(t))``,
with the static-gain table β_cmd = 0.5·θ_INS (tests/fixture_tables.py, sign +1), and
``ref(t)``/``β_ff(t)`` linear in time between the reference samples.
"""

import math

import numpy as np
import pytest

from fixture_tables import write_gain_table
from vega_loops.export import write_controller_table
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_OK, STATUS_SAFE_ZERO,
                                         ControllerRuntime, Measurement, RuntimeLimits)
from vega_gnc.controller_table import MEASUREMENT_NAMES
from vega_gnc.guidance_reference import GuidanceReference

NAMES = list(MEASUREMENT_NAMES)


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """β_cmd = 0.5·θ_INS, grid 0..3000 m/s, measurement sign +1."""
    return write_gain_table(tmp_path_factory.mktemp("gain") / "gain.npz")


@pytest.fixture(scope="module")
def reference():
    """θ_ref 0 → 0.02 rad, θ̇_ref 0.004 rad/s, z_ref 0, ż_ref 0.5 m/s, β_ff 0.001 → 0.003 rad
    over t = 0..1 s (the θ̇, ż columns differ from β_ff so that a wrong column shows)."""
    t = np.array([0.0, 1.0])
    ref = np.array([[0.0, 0.004, 0.0, 0.5], [0.02, 0.004, 0.0, 0.5]])
    ff = np.array([0.001, 0.003])
    return GuidanceReference(path="hand", t_s=t, reference=ref, beta_ff_rad=ff,
                             metadata={"input_names": NAMES})


def _m(stamp, pitch=0.0, v=500.0, valid=True, rate=0.0):
    return Measurement(stamp, pitch, rate, 0.0, 0.0, v, valid)


# ------------------------------------------------------------------ reference and feed-forward
def test_reference_and_feed_forward_enter_the_law(gain_table, reference):
    """At stamp 0.5 s: θ_ref = 0.01 rad, β_ff = 0.002 rad, so θ = 0.03 rad gives
    u = 0.5·(0.03 − 0.01) + 0.002 = 0.012 rad (used at 0.51 s: the reference is taken at the
    sample's stamp, where 0.51 s would give 0.5·(0.03 − 0.0102) + 0.00202 = 0.01192)."""
    rt = ControllerRuntime(gain_table, reference=reference)
    cmd = rt.step(_m(0.5, 0.03), now_s=0.51)
    assert cmd.status == STATUS_OK
    assert cmd.deflection_cmd_rad == pytest.approx(0.012, abs=1e-15)


def test_without_reference_the_law_is_the_bare_gain(gain_table):
    cmd = ControllerRuntime(gain_table).step(_m(0.5, 0.03))
    assert cmd.deflection_cmd_rad == pytest.approx(0.015, abs=1e-15)


def test_reference_held_beyond_its_last_sample(gain_table, reference):
    """At 3 s (past the last sample at 1 s): θ_ref = 0.02, β_ff = 0.003 → u = 0.5·0.01 + 0.003."""
    cmd = ControllerRuntime(gain_table, reference=reference).step(_m(3.0, 0.03))
    assert cmd.deflection_cmd_rad == pytest.approx(0.008, abs=1e-15)


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
