"""The on-board controller runtime at its limits: saturation both ways, staleness and hold limits
at their boundaries, velocity clamping at both grid edges, interpolation against a hand
computation from the table's raw matrices, and the status values.

Rules (vega_gnc/controller_runtime.py docstring, README "beyond ±6.5° → STATUS_LIMITED"):
a command BEYOND ±limit_rad is saturated to the limit and flagged LIMITED (exactly at the
limit: not beyond); a measurement "not older than max_age_s at the time of use" is fresh; a
held command is trusted while the input has been invalid for no longer than hold_limit_s;
"when several apply the most severe wins (SAFE_ZERO > HOLD_LAST > LIMITED > VELOCITY_CLAMPED
> OK)". Reference interpolation: element-wise (1 − w)·M[i] + w·M[i+1] with
w = (v − v_i)/(v_i+1 − v_i), written here from the arrays, not with ControllerTable.interpolate.
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from fixture_tables import write_gain_table
from vega_loops.export import write_controller_table
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_LIMITED, STATUS_OK,
                                         STATUS_SAFE_ZERO, STATUS_VELOCITY_CLAMPED,
                                         ControllerRuntime, Measurement, RuntimeLimits)

LIM = math.radians(6.5)
NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
GRID = [100.0, 400.0, 900.0]


@pytest.fixture(scope="module")
def gain_table(tmp_path_factory):
    """β_cmd = 0.5·θ_INS (static gain, measurement sign +1): u is known exactly."""
    return write_gain_table(tmp_path_factory.mktemp("gain") / "gain.npz")


@pytest.fixture(scope="module")
def dyn_table(tmp_path_factory):
    """A 3-state controller on three grid points, measurement sign −1."""
    rng = np.random.default_rng(11)
    A = -4.0 * np.eye(3) + 0.5 * rng.standard_normal((3, 3, 3))
    B = rng.standard_normal((3, 3, 4))
    C = rng.standard_normal((3, 1, 3))
    D = 0.05 * rng.standard_normal((3, 1, 4))
    meta = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    return write_controller_table(tmp_path_factory.mktemp("dyn") / "d.npz", GRID, A, B, C, D,
                                  dt_s=0.02, gamma=1.0, gamma_min=0.9,
                                  rate_bounds_mps2=[0.0, 36.0], metadata=meta)


@pytest.fixture(scope="module")
def rate_table(tmp_path_factory):
    """Same kind with two ρ̇ slices (0 and 36 m/s²)."""
    rng = np.random.default_rng(12)
    lead = (3, 2)
    A = -4.0 * np.eye(2) + 0.5 * rng.standard_normal(lead + (2, 2))
    B = rng.standard_normal(lead + (2, 4))
    C = rng.standard_normal(lead + (1, 2))
    D = 0.05 * rng.standard_normal(lead + (1, 4))
    meta = {"input_names": NAMES, "measurement_sign": -1, "output_name": "beta_cmd_rad",
            "units": {}, "weights": {}, "solver": {}}
    return write_controller_table(tmp_path_factory.mktemp("rate") / "r.npz", GRID, A, B, C, D,
                                  dt_s=0.02, gamma=1.0, gamma_min=0.9,
                                  rate_bounds_mps2=[0.0, 36.0], metadata=meta,
                                  rate_grid_mps2=[0.0, 36.0])


def _m(stamp, pitch=0.0, v=500.0, valid=True, rest=(0.0, 0.0, 0.0)):
    return Measurement(stamp, pitch, *rest, v, valid)


# ----------------------------------------------------------------------------- status values
def test_status_values_are_those_of_the_message():
    """The runtime's constants equal TvcCommand.msg's (read from the .msg text)."""
    msg = next(Path(__file__).resolve().parents[2].glob(
        "ros2_ws/src/vega_msgs/msg/TvcCommand.msg")).read_text()
    consts = {k: int(v) for k, v in re.findall(r"uint8 (STATUS_\w+)=(\d+)", msg)}
    assert consts == {"STATUS_OK": STATUS_OK, "STATUS_HOLD_LAST": STATUS_HOLD_LAST,
                      "STATUS_VELOCITY_CLAMPED": STATUS_VELOCITY_CLAMPED,
                      "STATUS_SAFE_ZERO": STATUS_SAFE_ZERO, "STATUS_LIMITED": STATUS_LIMITED}
    assert consts == {"STATUS_OK": 0, "STATUS_HOLD_LAST": 1, "STATUS_VELOCITY_CLAMPED": 2,
                      "STATUS_SAFE_ZERO": 3, "STATUS_LIMITED": 4}
    assert RuntimeLimits().limit_rad == LIM
    assert (RuntimeLimits().max_age_s, RuntimeLimits().hold_limit_s) == (0.032, 0.2)


# ----------------------------------------------------------------------------- saturation
@pytest.mark.parametrize("pitch, expected, status", [
    (1.0, LIM, STATUS_LIMITED),                          # +28.6° wanted
    (-1.0, -LIM, STATUS_LIMITED),                        # −28.6° wanted: flagged too
    (2 * LIM, LIM, STATUS_OK),                           # exactly +6.5°: not beyond
    (-2 * LIM, -LIM, STATUS_OK),                         # exactly −6.5°
    (2 * math.nextafter(LIM, 1.0), LIM, STATUS_LIMITED),     # one ulp beyond
    (2 * math.nextafter(-LIM, -1.0), -LIM, STATUS_LIMITED),
    (2 * math.nextafter(LIM, 0.0), math.nextafter(LIM, 0.0), STATUS_OK),
    (-0.1, -0.05, STATUS_OK),
])
def test_saturation_both_ways(gain_table, pitch, expected, status):
    """u = 0.5·θ exactly (multiplying by 0.5 is exact): beyond ±6.5° → clamped to the limit
    and LIMITED, at or inside it → the command itself and OK."""
    cmd = ControllerRuntime(gain_table).step(_m(1.0, pitch))
    assert cmd.status == status
    assert cmd.deflection_cmd_rad == expected


def test_saturation_of_a_dynamic_controller_both_signs(dyn_table):
    """A controller driven by a large error: each command is LIMITED exactly when the
    unlimited law (hand recursion on the raw matrices) is beyond ±6.5°, and then equals
    ±6.5° with the law's sign; both signs occur. The state follows the unlimited law."""
    g = np.asarray(dyn_table.grid_v_mps)
    rt = ControllerRuntime(dyn_table)
    x = np.zeros(3)
    seen, n_ok = set(), 0
    for k in range(60):
        y = np.array([0.4 * math.sin(0.3 * k), 0.1 * math.cos(0.2 * k), 5.0 * math.sin(0.17 * k),
                      -0.5 * math.cos(0.17 * k)])
        v = 250.0
        w = (v - g[0]) / (g[1] - g[0])
        Ad = (1 - w) * dyn_table.Ad[0] + w * dyn_table.Ad[1]
        Bd = (1 - w) * dyn_table.Bd[0] + w * dyn_table.Bd[1]
        Cd = (1 - w) * dyn_table.Cd[0] + w * dyn_table.Cd[1]
        Dd = (1 - w) * dyn_table.Dd[0] + w * dyn_table.Dd[1]
        u = (Cd @ x - Dd @ y).item()
        x = Ad @ x - Bd @ y
        cmd = rt.step(_m(0.02 * k, y[0], v, rest=tuple(y[1:])))
        if abs(u) > LIM:
            assert cmd.status == STATUS_LIMITED and cmd.deflection_cmd_rad == math.copysign(LIM, u)
            seen.add(math.copysign(1.0, u))
        else:
            assert cmd.status == STATUS_OK
            assert cmd.deflection_cmd_rad == pytest.approx(u, rel=1e-12, abs=1e-15)
            n_ok += 1
    assert seen == {1.0, -1.0} and n_ok >= 5
    np.testing.assert_allclose(rt.state, x, rtol=1e-11, atol=1e-14)


def test_limited_outranks_velocity_clamped(gain_table):
    """Both apply (velocity beyond the grid and a command beyond the limit): LIMITED wins."""
    for pitch in (1.0, -1.0):
        cmd = ControllerRuntime(gain_table).step(_m(1.0, pitch, v=5000.0))
        assert cmd.status == STATUS_LIMITED
        assert cmd.scheduling_velocity_mps == 3000.0
        assert cmd.deflection_cmd_rad == math.copysign(LIM, pitch)


# ----------------------------------------------------------------------------- staleness
@pytest.mark.parametrize("age_ms, fresh", [(0, True), (12, True), (31, True), (33, False),
                                           (50, False)])
def test_staleness_boundary_default_limit(gain_table, age_ms, fresh):
    """max_age 32 ms: 31 ms old is used, 33 ms old is stale (the last command is held)."""
    rt = ControllerRuntime(gain_table)
    first = rt.step(_m(10.0, 0.02), now_s=10.012)
    assert first.status == STATUS_OK and first.deflection_cmd_rad == 0.01
    cmd = rt.step(_m(10.02, 0.06), now_s=10.02 + age_ms / 1000.0)
    if fresh:
        assert cmd.status == STATUS_OK and cmd.deflection_cmd_rad == 0.03
    else:
        assert cmd.status == STATUS_HOLD_LAST and cmd.deflection_cmd_rad == 0.01


def test_stale_first_measurement_is_safe_zero(gain_table):
    rt = ControllerRuntime(gain_table)
    cmd = rt.step(_m(10.0, 0.02), now_s=10.033)
    assert cmd.status == STATUS_SAFE_ZERO and cmd.deflection_cmd_rad == 0.0
    assert rt.step(_m(10.02, 0.02), now_s=10.051).status == STATUS_OK      # 31 ms


def test_staleness_and_hold_exactly_at_their_limits(gain_table):
    """With limits that are exact binary fractions: an age equal to max_age is 'not older' →
    used; 1 µs more is stale. An invalid input exactly hold_limit after the last valid one was
    *used* (receive side) is still held; 1 µs later it is not (times resolve to 1 µs)."""
    limits = RuntimeLimits(max_age_s=0.03125, hold_limit_s=0.25)
    rt = ControllerRuntime(gain_table, limits)
    assert rt.step(_m(2.0, 0.125), now_s=2.03125).status == STATUS_OK      # used at 2.03125
    late = rt.step(_m(2.0625, 0.125), now_s=2.0625 + 0.03125 + 1e-6)
    assert late.status == STATUS_HOLD_LAST
    held = rt.step(_m(2.28125, 0.125, valid=False))                        # 2.03125 + 0.25
    assert held.status == STATUS_HOLD_LAST and held.deflection_cmd_rad == 0.0625
    gone = rt.step(_m(2.28125 + 1e-6, 0.125, valid=False))
    assert gone.status == STATUS_SAFE_ZERO and gone.deflection_cmd_rad == 0.0


def test_age_of_exactly_max_age_on_the_ms_grid_is_fresh_at_every_flight_time(gain_table):
    verdicts = set()
    for sample_ms in range(10_000, 12_000, 20):
        rt = ControllerRuntime(gain_table)
        cmd = rt.step(_m(sample_ms / 1000.0, 0.02), now_s=(sample_ms + 32) / 1000.0)
        verdicts.add(cmd.status)
    assert verdicts == {STATUS_OK}


def test_hold_of_exactly_hold_limit_on_the_ms_grid_is_held_at_every_flight_time(gain_table):
    verdicts = set()
    for sample_ms in range(10_000, 12_000, 20):
        rt = ControllerRuntime(gain_table)
        rt.step(_m(sample_ms / 1000.0, 0.02))
        cmd = rt.step(_m((sample_ms + 200) / 1000.0, 0.02, valid=False))
        verdicts.add(cmd.status)
    assert verdicts == {STATUS_HOLD_LAST}


# ----------------------------------------------------------------------------- hold limit
@pytest.mark.parametrize("after_ms, status", [(20, STATUS_HOLD_LAST), (199, STATUS_HOLD_LAST),
                                              (201, STATUS_SAFE_ZERO), (400, STATUS_SAFE_ZERO)])
def test_hold_limit_boundary_default(dyn_table, after_ms, status):
    """Invalid input 199 ms after the last valid one: the last command is held and the state
    frozen; 201 ms after: zero command and the state reset (hold limit 0.2 s)."""
    rt = ControllerRuntime(dyn_table)
    y = (0.01, 0.002, 0.3, 0.05)
    rt.step(Measurement(10.0, *y, 250.0))
    last = rt.step(Measurement(10.02, *y, 250.0))
    state = rt.state
    assert last.status == STATUS_OK and last.deflection_cmd_rad != 0.0
    t = 10.02 + after_ms / 1000.0
    cmd = rt.step(Measurement(t, *y, 250.0, False))
    assert cmd.status == status
    if status == STATUS_HOLD_LAST:
        assert cmd.deflection_cmd_rad == last.deflection_cmd_rad
        np.testing.assert_array_equal(rt.state, state)
    else:
        assert cmd.deflection_cmd_rad == 0.0 and np.all(rt.state == 0.0)


@pytest.mark.parametrize("bad", [dict(pitch=math.nan), dict(pitch=math.inf),
                                 dict(pitch=-math.inf), dict(v=math.nan), dict(v=math.inf),
                                 dict(valid=False), dict(stamp=math.nan)])
def test_non_finite_input_is_held_not_used(gain_table, bad):
    """NaN/inf in a used field, a non-finite velocity or stamp, or valid = False: the last
    (finite) command is held — never NaN out with STATUS_OK."""
    rt = ControllerRuntime(gain_table)
    ok = rt.step(_m(1.0, 0.04))
    kw = dict(stamp=1.02, pitch=0.04, v=500.0, valid=True)
    kw.update(bad)
    cmd = rt.step(_m(kw["stamp"], kw["pitch"], kw["v"], kw["valid"]), now_s=1.02)
    assert cmd.status == STATUS_HOLD_LAST
    assert cmd.deflection_cmd_rad == ok.deflection_cmd_rad == 0.02


def test_repeated_or_older_stamp_is_held(gain_table):
    """A stamp equal to or older than the last one is not fresh: held (the state frozen); the
    next strictly later stamp is used again."""
    rt = ControllerRuntime(gain_table)
    assert rt.step(_m(1.0, 0.04)).deflection_cmd_rad == 0.02
    for stamp in (1.0, 0.98):
        cmd = rt.step(_m(stamp, 0.08), now_s=1.0)
        assert cmd.status == STATUS_HOLD_LAST and cmd.deflection_cmd_rad == 0.02
    cmd = rt.step(_m(1.02, 0.08))
    assert cmd.status == STATUS_OK and cmd.deflection_cmd_rad == 0.04


def _finite_within_limits(cmds):
    return all(math.isfinite(c.deflection_cmd_rad) and abs(c.deflection_cmd_rad) <= LIM
               for c in cmds)


@pytest.fixture(scope="module")
def flight_table():
    """The committed LPV controller table (the one that flies)."""
    from vega_lpv.pipeline import DEFAULT_TABLE
    from vega_gnc.controller_table import load_controller_table

    return load_controller_table(DEFAULT_TABLE)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
@pytest.mark.parametrize("field", [0, 1])
@pytest.mark.parametrize("huge", [1.7e308, -1.7e308])
def test_huge_finite_measurement_never_gives_nan_with_status_ok(flight_table, huge, field):
    rt = ControllerRuntime(flight_table)
    y = [0.0, 0.0, 0.0, 0.0]
    y[field] = huge
    cmds = [rt.step(Measurement(0.0, 0.001, 0.0, 0.0, 0.0, 300.0)),
            rt.step(Measurement(0.02, *y, 300.0))]
    cmds += [rt.step(Measurement(0.02 * k, 0.001, 0.0, 0.0, 0.0, 300.0)) for k in range(2, 8)]
    assert _finite_within_limits(cmds)
    assert all(math.isfinite(c.deflection_cmd_rad) for c in cmds if c.status == STATUS_OK)
    assert np.all(np.isfinite(rt.state))


def test_huge_measurement_with_small_gains_stays_finite(dyn_table):
    """A finite but implausible measurement (|pitch| > π) is not used: the last command is
    held, the state stays finite."""
    rt = ControllerRuntime(dyn_table)
    cmds = [rt.step(Measurement(0.0, 0.01, 0.0, 0.0, 0.0, 250.0)),
            rt.step(Measurement(0.02, 1.7e308, 0.0, 0.0, 0.0, 250.0))]
    assert cmds[1].status == STATUS_HOLD_LAST and _finite_within_limits(cmds)
    assert np.all(np.isfinite(rt.state))


def test_future_stamp_cannot_extend_the_hold(gain_table):
    rt = ControllerRuntime(gain_table)
    rt.step(_m(10.0, 0.02), now_s=10.012)
    rt.step(_m(11.0, 0.02), now_s=10.032)            # stamp 1 s ahead of the receive clock
    cmd = rt.step(_m(10.3, 0.02, valid=False), now_s=10.3)
    assert cmd.status == STATUS_SAFE_ZERO and cmd.deflection_cmd_rad == 0.0


# ----------------------------------------------------------------------------- velocity clamping
def _hand_step(table, v, y, sign=-1.0, x=None):
    """u and x⁺ at velocity v from the raw arrays (clamped to the grid by hand)."""
    g = np.asarray(table.grid_v_mps, dtype=float)
    vc = min(max(v, g[0]), g[-1])
    i = min(int(np.sum(g <= vc)) - 1, len(g) - 2)
    w = (vc - g[i]) / (g[i + 1] - g[i])
    M = [(1 - w) * getattr(table, k)[i] + w * getattr(table, k)[i + 1]
         for k in ("Ad", "Bd", "Cd", "Dd")]
    x = np.zeros(table.n_states) if x is None else x
    y = sign * np.asarray(y, dtype=float)
    return (M[2] @ x + M[3] @ y).item(), M[0] @ x + M[1] @ y, vc


@pytest.mark.parametrize("v, status, v_sched", [
    (GRID[0] - 1.0, STATUS_VELOCITY_CLAMPED, GRID[0]),
    (math.nextafter(GRID[0], 0.0), STATUS_VELOCITY_CLAMPED, GRID[0]),
    (GRID[0], STATUS_OK, GRID[0]),
    (GRID[0] + 1.0, STATUS_OK, GRID[0] + 1.0),
    (GRID[-1] - 1.0, STATUS_OK, GRID[-1] - 1.0),
    (GRID[-1], STATUS_OK, GRID[-1]),
    (math.nextafter(GRID[-1], 1e4), STATUS_VELOCITY_CLAMPED, GRID[-1]),
    (GRID[-1] + 1.0, STATUS_VELOCITY_CLAMPED, GRID[-1]),
    (-50.0, STATUS_VELOCITY_CLAMPED, GRID[0]),
])
def test_velocity_clamping_at_both_edges(dyn_table, v, status, v_sched):
    y = (0.01, -0.002, 0.4, 0.03)
    rt = ControllerRuntime(dyn_table, RuntimeLimits(limit_rad=1e9))
    u_ref, x_ref, vc = _hand_step(dyn_table, v, y)
    cmd = rt.step(Measurement(0.0, *y, v))
    assert vc == v_sched
    assert cmd.status == status and cmd.scheduling_velocity_mps == v_sched
    assert cmd.deflection_cmd_rad == pytest.approx(u_ref, rel=1e-12, abs=1e-15)
    np.testing.assert_allclose(rt.state, x_ref, rtol=1e-12, atol=1e-15)


# ----------------------------------------------------------------------------- interpolation
def test_interpolation_between_grid_points_by_hand(dyn_table):
    """Thirty steps at velocities crossing both grid intervals: u and the state follow the
    hand-interpolated matrices of the raw table arrays (w computed here)."""
    rt = ControllerRuntime(dyn_table, RuntimeLimits(limit_rad=1e9))
    rng = np.random.default_rng(4)
    x = np.zeros(3)
    for k, v in enumerate(np.linspace(120.0, 880.0, 30)):
        y = 1e-2 * rng.standard_normal(4)
        u_ref, x, _ = _hand_step(dyn_table, float(v), y, x=x)
        cmd = rt.step(Measurement(0.02 * k, *y, float(v)))
        assert cmd.status == STATUS_OK and cmd.scheduling_velocity_mps == float(v)
        assert cmd.deflection_cmd_rad == pytest.approx(u_ref, rel=1e-11, abs=1e-15)
    np.testing.assert_allclose(rt.state, x, rtol=1e-11, atol=1e-15)


def test_interpolation_midpoint_is_the_mean_of_the_neighbours(dyn_table):
    """At v = 250 (midway 100–400) and at v = 400 (a grid point) from a zero state:
    u = (Dd[0] + Dd[1])/2 · (−y) and u = Dd[1] · (−y) (hand, exact weights 1/2 and 1)."""
    y = np.array([0.02, 0.01, -0.3, 0.04])
    unlimited = RuntimeLimits(limit_rad=1e9)
    mid = ControllerRuntime(dyn_table, unlimited).step(Measurement(0.0, *y, 250.0))
    assert mid.deflection_cmd_rad == pytest.approx(
        (-(0.5 * dyn_table.Dd[0] + 0.5 * dyn_table.Dd[1]) @ y).item(), rel=1e-13)
    at = ControllerRuntime(dyn_table, unlimited).step(Measurement(0.0, *y, 400.0))
    assert at.deflection_cmd_rad == pytest.approx((-dyn_table.Dd[1] @ y).item(), rel=1e-13)


@pytest.mark.parametrize("rate, s", [(None, 1.0), (0.0, 0.0), (9.0, 0.25), (36.0, 1.0),
                                     (-5.0, 0.0), (50.0, 1.0)])
def test_rate_slice_interpolation_by_hand(rate_table, rate, s):
    """ρ̇ slices: (1 − s)·slice0 + s·slice1 with s = (ρ̇ − 0)/36 clamped to [0, 1]; the default
    (None) is the upper slice; then linear in velocity."""
    y = np.array([0.02, -0.01, 0.3, 0.04])
    v = 700.0
    g = np.asarray(rate_table.grid_v_mps)
    w = (v - g[1]) / (g[2] - g[1])
    mats = {}
    for k in ("Ad", "Bd", "Cd", "Dd"):
        arr = getattr(rate_table, k)
        lo = (1 - s) * arr[1][0] + s * arr[1][1]
        hi = (1 - s) * arr[2][0] + s * arr[2][1]
        mats[k] = (1 - w) * lo + w * hi
    rt = ControllerRuntime(rate_table, RuntimeLimits(limit_rad=1e9), rate_mps2=rate)
    first = rt.step(Measurement(0.0, *y, v))
    second = rt.step(Measurement(0.02, *y, v))
    x1 = mats["Bd"] @ (-y)
    assert first.deflection_cmd_rad == pytest.approx((mats["Dd"] @ (-y)).item(), rel=1e-12)
    assert second.deflection_cmd_rad == pytest.approx(
        (mats["Cd"] @ x1 + mats["Dd"] @ (-y)).item(), rel=1e-12)
    np.testing.assert_allclose(rt.state, mats["Ad"] @ x1 + mats["Bd"] @ (-y), rtol=1e-12)


def test_hold_runs_from_when_the_last_measurement_was_used(gain_table):
    """The hold limit counts from the receive time of the last measurement used, not from its
    stamp: a measurement stamped 10.000 s and used at 10.032 s (32 ms old, still fresh) holds
    until 10.232 s; at 10.220 s (220 ms after its stamp) the command is still held."""
    rt = ControllerRuntime(gain_table)
    used = rt.step(_m(10.0, 0.02), now_s=10.032)
    assert used.status == STATUS_OK
    cmd = rt.step(_m(10.2, 0.02, valid=False), now_s=10.220)
    assert cmd.status == STATUS_HOLD_LAST and cmd.deflection_cmd_rad == used.deflection_cmd_rad
    cmd = rt.step(_m(10.24, 0.02, valid=False), now_s=10.240)
    assert cmd.status == STATUS_SAFE_ZERO and cmd.deflection_cmd_rad == 0.0


def test_a_future_stamp_does_not_block_the_measurements_after_it(gain_table):
    """A measurement stamped in the future is refused and does not become the 'latest stamp':
    the next ordinary measurement is used (one forged stamp cannot silence the INS)."""
    rt = ControllerRuntime(gain_table)
    assert rt.step(_m(10.0, 0.02), now_s=10.012).status == STATUS_OK
    assert rt.step(_m(99.0, 0.02), now_s=10.032).status == STATUS_HOLD_LAST
    assert rt.step(_m(10.04, 0.02), now_s=10.052).status == STATUS_OK


def test_a_repeated_stamp_is_refused_even_after_a_safe_zero(gain_table):
    """The newest stamp survives the reset of a SAFE_ZERO, so a message repeated after it is
    not used."""
    rt = ControllerRuntime(gain_table)
    assert rt.step(_m(10.02, 0.02, valid=False)).status == STATUS_SAFE_ZERO
    assert rt.step(_m(10.02, 0.02)).status == STATUS_SAFE_ZERO     # same stamp again
    assert rt.step(_m(10.04, 0.02)).status == STATUS_OK
