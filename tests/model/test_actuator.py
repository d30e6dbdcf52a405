"""TVC actuator: exact linear response, limiter law, β̈ consistency, robustness, parameter
and state checks, and the batch path ``run()`` against ``step()``.

The limiter law at its boundaries, both signs: test_actuator_limiter.py."""

import math

import numpy as np
import pytest

from vega_model.actuator import ActuatorParams, TvcActuator, linear_actuator_ss
from actuator_reference import analytic_step
from vega_model.vehicle_data import load_vehicle_data

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def params():
    return ActuatorParams.from_vehicle(load_vehicle_data())


def test_parameters_from_vehicle(params):
    assert params.wn_radps == 100.0           # thesis code: 1e4/(s² + 100 s + 1e4)
    assert params.zeta == 0.5
    assert params.position_limit_rad == pytest.approx(6.5 * DEG)   # thesis Table 3.1
    assert params.rate_limit_radps == pytest.approx(20.0 * DEG)    # vehicle.yaml assumption
    assert params.dt_s == pytest.approx(1e-3)
    scaled = ActuatorParams.from_vehicle(load_vehicle_data(), bandwidth_scale=1.1)
    assert scaled.wn_radps == pytest.approx(110.0) and scaled.zeta == 0.5


def test_linear_model_is_the_thesis_transfer_function(params):
    A, B, C, D = linear_actuator_ss(params)
    for w in (0.0, 10.0, 100.0, 1000.0):
        s = 1j * w
        g = C @ np.linalg.solve(s * np.eye(2) - A, B) + D
        expected = 1e4 / (s ** 2 + 100.0 * s + 1e4)
        assert g[0, 0] == pytest.approx(expected, rel=1e-12)          # β / β_cmd
        assert g[1, 0] == pytest.approx(s * expected, rel=1e-12, abs=1e-12)   # β̇
        assert g[2, 0] == pytest.approx(s ** 2 * expected, rel=1e-12, abs=1e-12)  # β̈


def test_small_step_matches_analytic_response(params):
    """Unlimited: samples equal the exact continuous response (|β̇| peak ≈ 5.5°/s < 20°/s)."""
    act = TvcActuator(params)
    u = 0.1 * DEG
    beta, beta_dot, beta_ddot = act.advance(u, 300)
    t = params.dt_s * np.arange(1, 301)
    b_ref, r_ref = analytic_step(u, t, params.wn_radps, params.zeta)
    assert np.max(np.abs(beta - b_ref)) < 1e-9 * u
    assert np.max(np.abs(beta_dot - r_ref)) < 1e-9 * u * params.wn_radps
    np.testing.assert_allclose(beta_ddot, 1e4 * (u - b_ref) - 100.0 * r_ref, rtol=0,
                               atol=1e-9 * u * params.wn_radps ** 2)
    # 16.3 % overshoot of a ζ = 0.5 second-order system at t = π/ω_d = 36.3 ms
    assert np.max(beta) / u == pytest.approx(1.0 + math.exp(-math.pi / math.sqrt(3.0)), rel=1e-3)
    assert np.max(np.abs(beta_dot)) < params.rate_limit_radps


def test_steady_state(params):
    act = TvcActuator(params)
    beta, beta_dot, beta_ddot = act.advance(-0.3 * DEG, 1000)
    assert beta[-1] == pytest.approx(-0.3 * DEG, abs=1e-15)
    assert abs(beta_dot[-1]) < 1e-15 and abs(beta_ddot[-1]) < 1e-12


def test_rate_limit_active_and_respected(params):
    act = TvcActuator(params)
    beta, beta_dot, beta_ddot = act.advance(5.0 * DEG, 600)
    rate = params.rate_limit_radps
    assert np.max(np.abs(beta_dot)) == rate                   # reached, never exceeded
    on_limit = beta_dot == rate
    assert on_limit.sum() > 100                               # 5° at 20°/s takes ≈ 0.25 s
    assert np.all(beta_ddot[on_limit] == 0.0)                 # held on the limit
    steps = np.diff(np.concatenate(([0.0], beta)))
    assert np.max(np.abs(steps)) <= rate * params.dt_s * (1 + 1e-12)
    # on the limit the nozzle moves exactly R·dt per step
    idx = np.flatnonzero(on_limit[1:] & on_limit[:-1]) + 1
    np.testing.assert_allclose(steps[idx], rate * params.dt_s, rtol=1e-12)
    assert beta[-1] == pytest.approx(5.0 * DEG, abs=1e-9)     # and still settles


def test_position_limit(params):
    act = TvcActuator(params)
    pos = params.position_limit_rad
    beta, beta_dot, beta_ddot = act.advance(10.0 * DEG, 1000)
    assert np.max(beta) == pos and np.all(beta <= pos)
    assert beta[-1] == pos and beta_dot[-1] == 0.0 and beta_ddot[-1] == 0.0
    # leaves the stop when the command comes back inside
    beta2, beta_dot2, _ = act.advance(0.0, 1000)
    assert beta_dot2[0] < 0.0 and beta2[0] < pos
    assert beta2[-1] == pytest.approx(0.0, abs=1e-9)
    # the negative stop as well
    beta3, _, _ = act.advance(-1.0, 2000)
    assert np.min(beta3) == -pos and beta3[-1] == -pos


def test_beta_ddot_consistent_with_finite_differences(params):
    """Over each step β̇ changes by the trapezoidal integral of β̈ (O(dt²) error)."""
    act = TvcActuator(params)
    _, beta_dot, beta_ddot = act.advance(0.2 * DEG, 200)
    rd = np.concatenate(([0.0], beta_dot))
    acc = np.concatenate(([act.params.wn_radps ** 2 * 0.2 * DEG], beta_ddot))  # β̈(0+) = ω²u
    fd = np.diff(rd) / params.dt_s
    trap = 0.5 * (acc[1:] + acc[:-1])
    assert np.max(np.abs(fd - trap)) < 2e-3 * np.max(np.abs(acc))
    # and not merely small: the β̈ signal is large and changes sign
    assert np.max(acc) > 0 > np.min(acc)


def test_nan_command_holds_last_command(params):
    a, b = TvcActuator(params), TvcActuator(params)
    a.advance(0.5 * DEG, 20)
    b.advance(0.5 * DEG, 20)
    for cmd in (math.nan, math.inf, -math.inf):
        assert a.step(cmd) == b.step(0.5 * DEG)
    # after reset the held command is the reset position
    a.reset(1.0 * DEG)
    assert a.step(math.nan) == (1.0 * DEG, 0.0, 0.0)


def test_never_raises_on_finite_input_and_stays_bounded(params):
    act = TvcActuator(params)
    rng = np.random.default_rng(1)
    for cmd in list(rng.uniform(-1e300, 1e300, 200)) + [1e308, -1e308, 0.0]:
        b, r, a = act.step(float(cmd))
        assert abs(b) <= params.position_limit_rad and abs(r) <= params.rate_limit_radps
        assert not math.isnan(a)


def test_advance_equals_repeated_steps(params):
    a, b = TvcActuator(params), TvcActuator(params)
    cmds = np.linspace(-3.0, 8.0, 50) * DEG
    batch = a.advance(cmds, 50)
    single = np.array([b.step(c) for c in cmds]).T
    np.testing.assert_array_equal(np.array(batch), single)
    with pytest.raises(ValueError):
        a.advance([0.0, 0.0], 3)


def test_invalid_parameters_rejected():
    with pytest.raises(ValueError):
        ActuatorParams(wn_radps=0.0, zeta=0.5, position_limit_rad=0.1, rate_limit_radps=0.3,
                       dt_s=1e-3)
    with pytest.raises(ValueError):
        ActuatorParams(wn_radps=100.0, zeta=0.5, position_limit_rad=0.1,
                       rate_limit_radps=math.nan, dt_s=1e-3)



def _kw(**over):
    kw = dict(wn_radps=100.0, zeta=0.5, position_limit_rad=0.1, rate_limit_radps=0.3,
              dt_s=1e-3)
    kw.update(over)
    return kw


def test_damping_ratio_zero_is_accepted_nan_and_negative_are_not():
    assert ActuatorParams(**_kw(zeta=0.0)).zeta == 0.0          # undamped: allowed (>= 0)
    for bad in (math.nan, math.inf, -0.1):
        with pytest.raises(ValueError, match="zeta"):
            ActuatorParams(**_kw(zeta=bad))


def test_advance_zero_steps_gives_empty_arrays_and_negative_is_refused(params):
    act = TvcActuator(params)
    beta, beta_dot, beta_ddot = act.advance(1.0 * DEG, 0)
    assert beta.shape == beta_dot.shape == beta_ddot.shape == (0,)
    with pytest.raises(ValueError):
        act.advance(1.0 * DEG, -1)


def test_reset_defaults_to_rest_at_zero(params):
    act = TvcActuator(params)
    act.advance(0.1 * DEG, 10)                  # moving: β, β̇, β̈ all non-zero
    assert all(v != 0.0 for v in act.state)
    act.reset()
    assert act.state == (0.0, 0.0, 0.0) and act.command_rad == 0.0
    assert act.step(math.nan) == (0.0, 0.0, 0.0)
    act.reset(1.0)                               # beyond the stop: clamped, at rest
    assert act.state == (params.position_limit_rad, 0.0, 0.0)
    act.reset(-1.0)
    assert act.state == (-params.position_limit_rad, 0.0, 0.0)


def test_run_equals_step_by_step_and_reports_the_held_commands(params):
    rng = np.random.default_rng(11)
    cmds = list(rng.uniform(-12.0, 12.0, 400) * DEG) + [math.nan, math.inf, -math.inf] \
        + [9.0 * DEG] * 600 + [-9.0 * DEG] * 1000 + [math.nan] * 5
    a, b = TvcActuator(params, beta0_rad=1.0 * DEG), TvcActuator(params, beta0_rad=1.0 * DEG)
    betas, rates, accels, helds = a.run(cmds)
    ref = np.array([b.step(c) for c in cmds])
    np.testing.assert_array_equal(np.array([betas, rates, accels]).T, ref)
    assert a.state == b.state and a.command_rad == b.command_rad == -9.0 * DEG
    # held command: the last finite one (a NaN right after the random block holds its last)
    assert helds[400] == helds[399] == cmds[399] and helds[-1] == -9.0 * DEG
    assert helds[:400] == cmds[:400]
    # limits both ways in the batch path
    assert max(betas) == params.position_limit_rad and min(betas) == -params.position_limit_rad
    assert max(rates) == params.rate_limit_radps and min(rates) == -params.rate_limit_radps
    # an empty batch changes nothing
    before = a.state
    assert a.run([]) == ([], [], [], []) and a.state == before


def test_run_small_step_matches_analytic_response(params):
    """The batch path is the exact ZOH response when unlimited (independent of step())."""
    act = TvcActuator(params)
    u = 0.1 * DEG
    betas, rates, accels, _ = act.run([u] * 100)
    for k in (0, 9, 36, 99):
        t = params.dt_s * (k + 1)
        b_ref, r_ref = analytic_step(u, t, params.wn_radps, params.zeta)
        assert betas[k] == pytest.approx(b_ref, rel=1e-9)
        assert rates[k] == pytest.approx(r_ref, rel=1e-9)
        assert accels[k] == pytest.approx(1e4 * (u - b_ref) - 100.0 * r_ref, rel=1e-7)


@pytest.mark.parametrize("zeta", [0.0, 0.2, 0.5, 0.9, 0.9999996, 1.0, 1.0000004, 1.3, 2.0])
@pytest.mark.parametrize("wn", [30.0, 90.0, 100.0, 110.0, 300.0])
def test_closed_form_hold_is_the_matrix_exponential(zeta, wn):
    """The closed-form Φ and one unlimited step equal scipy's expm of [[A, B], [0, 0]]·dt
    (the independent reference: Φ x + Γ u) to 1e-13 relative, over damping ratios 0–2
    (under-, critically and over-damped) and natural frequencies 0.3–3× the vehicle's, at
    the 1 kHz physics step. ζ = 1 ∓ 4e-7 puts ω_d·dt just below 1e-4 (real and imaginary),
    where sin(x)/x is taken from its series: an error in the series' x²/6 term shows there
    (≈ 1e-9 of Φ₁₂)."""
    from scipy.linalg import expm

    from vega_model.actuator import zoh_transition

    p = ActuatorParams(wn_radps=wn, zeta=zeta, position_limit_rad=0.1, rate_limit_radps=10.0,
                       dt_s=1e-3)
    A, B, _, _ = linear_actuator_ss(p)
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[:2, 2:] = A, B
    e = expm(aug * p.dt_s)
    np.testing.assert_allclose(np.array(zoh_transition(p)), e[:2, :2], rtol=1e-13, atol=0.0)
    act = TvcActuator(p, beta0_rad=0.01)
    act.beta_dot_radps = -0.05
    want = e[:2, :2] @ [0.01, -0.05] + e[:2, 2] * 0.03
    b, r, _ = act.step(0.03)
    np.testing.assert_allclose([b, r], want, rtol=1e-13, atol=1e-18)
