"""The on-board controller runtime: scheduled update, safe behaviour on bad input."""

import math

import numpy as np
import pytest

from vega_loops.export import write_controller_table
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_LIMITED, STATUS_OK,
                                         STATUS_SAFE_ZERO, STATUS_VELOCITY_CLAMPED,
                                         ControllerRuntime, Measurement, RuntimeLimits)

NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
GRID = [100.0, 400.0, 900.0]
DT = 0.02


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    rng = np.random.default_rng(7)
    n = 3
    A = -4.0 * np.eye(n) + 0.5 * rng.standard_normal((3, n, n))
    B = rng.standard_normal((3, n, 4))
    C = rng.standard_normal((3, 1, n))
    D = 0.01 * rng.standard_normal((3, 1, 4))
    meta = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    return write_controller_table(tmp_path_factory.mktemp("t") / "c.npz", GRID, A, B, C, D,
                                  dt_s=DT, gamma=1.0, gamma_min=0.9,
                                  rate_bounds_mps2=[5.4, 36.4], metadata=meta)


def _meas(k, y, v, valid=True):
    return Measurement(k * DT, *y, v, valid)


def test_matches_reference_update(table):
    """u_k = Cd(v)x_k + Dd(v)y_k, x_{k+1} = Ad(v)x_k + Bd(v)y_k with y = −measurement."""
    rng = np.random.default_rng(3)
    rt = ControllerRuntime(table, RuntimeLimits(limit_rad=1e9))
    x = np.zeros(3)
    for k in range(50):
        y = 1e-3 * rng.standard_normal(4)
        v = 150.0 + 12.0 * k
        Ad, Bd, Cd, Dd = table.interpolate(v)
        u_ref = (Cd @ x - Dd @ y).item()
        x = Ad @ x - Bd @ y
        cmd = rt.step(_meas(k, y, v))
        assert cmd.status == STATUS_OK
        assert cmd.deflection_cmd_rad == pytest.approx(u_ref, rel=1e-12, abs=1e-15)
        assert cmd.scheduling_velocity_mps == v
    assert np.allclose(rt.state, x, rtol=1e-12, atol=1e-15)


def test_invalid_input_holds_then_goes_safe(table):
    rt = ControllerRuntime(table, RuntimeLimits(limit_rad=1e9, hold_limit_s=0.1))
    y = [0.01, 0.0, 0.0, 0.0]
    first = rt.step(_meas(0, y, 200.0))
    state = rt.state
    nan = rt.step(_meas(1, [math.nan, 0, 0, 0], 200.0))
    assert nan.status == STATUS_HOLD_LAST and nan.deflection_cmd_rad == first.deflection_cmd_rad
    assert np.array_equal(rt.state, state)  # frozen while holding
    flagged = rt.step(_meas(2, y, 200.0, valid=False))
    assert flagged.status == STATUS_HOLD_LAST
    late = rt.step(_meas(8, [math.inf, 0, 0, 0], 200.0))  # 0.16 s after the last valid one
    assert late.status == STATUS_SAFE_ZERO and late.deflection_cmd_rad == 0.0
    assert np.all(rt.state == 0.0)
    again = rt.step(_meas(9, y, 200.0))
    assert again.status == STATUS_OK and again.deflection_cmd_rad == pytest.approx(
        first.deflection_cmd_rad)


def test_stale_and_out_of_order_stamps(table):
    rt = ControllerRuntime(table, RuntimeLimits(limit_rad=1e9))
    y = [0.01, 0.0, 0.0, 0.0]
    ok = rt.step(_meas(5, y, 200.0))
    assert rt.step(_meas(4, y, 200.0)).status == STATUS_HOLD_LAST          # older stamp
    assert rt.step(_meas(5, y, 200.0)).status == STATUS_HOLD_LAST          # repeated stamp
    stale = rt.step(_meas(6, y, 200.0), now_s=6 * DT + 0.05)               # 50 ms old
    assert stale.status == STATUS_HOLD_LAST and stale.deflection_cmd_rad == ok.deflection_cmd_rad


def test_no_valid_measurement_yet_is_safe_zero(table):
    rt = ControllerRuntime(table)
    cmd = rt.step(_meas(0, [0.1, 0, 0, 0], math.nan))
    assert cmd.status == STATUS_SAFE_ZERO and cmd.deflection_cmd_rad == 0.0


def test_velocity_outside_grid_is_clamped(table):
    y = [0.01, 0.002, 0.5, 0.1]
    lo = ControllerRuntime(table, RuntimeLimits(limit_rad=1e9))
    at_end = ControllerRuntime(table, RuntimeLimits(limit_rad=1e9))
    below = lo.step(_meas(0, y, 20.0))
    ref = at_end.step(_meas(0, y, GRID[0]))
    assert below.status == STATUS_VELOCITY_CLAMPED and ref.status == STATUS_OK
    assert below.deflection_cmd_rad == pytest.approx(ref.deflection_cmd_rad, rel=1e-14)
    # the reported scheduling velocity is the one the matrices belong to (TvcCommand field doc)
    assert below.scheduling_velocity_mps == GRID[0] == ref.scheduling_velocity_mps
    above = ControllerRuntime(table, RuntimeLimits(limit_rad=1e9)).step(_meas(0, y, 1e4))
    assert above.status == STATUS_VELOCITY_CLAMPED
    assert above.scheduling_velocity_mps == GRID[-1]


def test_command_limited_to_actuator_range(table):
    rt = ControllerRuntime(table)
    cmd = rt.step(_meas(0, [3.0, 5.0, 500.0, 50.0], 200.0))     # large, still plausible
    assert cmd.status == STATUS_LIMITED
    assert abs(cmd.deflection_cmd_rad) == pytest.approx(math.radians(6.5))


def test_garbage_never_raises(table):
    rt = ControllerRuntime(table)
    cmd = rt.step(Measurement("x", "y", None, 0, 0, 0, True))
    assert cmd.status == STATUS_SAFE_ZERO and cmd.deflection_cmd_rad == 0.0
