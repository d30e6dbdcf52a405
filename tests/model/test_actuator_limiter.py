"""TVC actuator: the limiter law at its boundaries, for both signs, through ``step()`` and
the batch ``run()``.

The rate limit (β̈ held at 0 on it, reported when the law pulls back inside), the stops
(resting on them, arriving exactly on them, leaving them) and a linear step that ends exactly
on the rate limit. Independent references: the analytic step response of
ω²/(s² + 2ζω s + ω²) (ζ < 1), the limiter law as the class docstring states it
(hand-evaluated at its boundaries), and the odd symmetry of the law (every operation of it is
sign-symmetric, so the response to −u is exactly minus the response to u: a mistake on one
side only breaks it).
"""

import math

import numpy as np
import pytest

from vega_model.actuator import ActuatorParams, TvcActuator
from actuator_reference import analytic_step
from vega_model.vehicle_data import load_vehicle_data

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def params():
    return ActuatorParams.from_vehicle(load_vehicle_data())


def _advance(act, u, n, path):
    """n steps with command u through step() (path "step") or the batch run() ("run")."""
    if path == "step":
        return act.advance(u, n)
    betas, rates, accels, _ = act.run([u] * n)
    return np.array(betas), np.array(rates), np.array(accels)


PATHS = ("step", "run")


def test_response_is_odd(params):
    """Commands −u give exactly −(response to u): rate limit, stops, leaving them, NaN hold."""
    rng = np.random.default_rng(5)
    cmds = np.concatenate([np.full(400, 5.0 * DEG), np.full(300, -2.0 * DEG),
                           np.full(600, 20.0 * DEG), np.full(200, 0.0),
                           [math.nan] * 50, rng.uniform(-10.0, 10.0, 300) * DEG,
                           np.full(300, params.position_limit_rad + 5e-5)])
    a, b = TvcActuator(params), TvcActuator(params)
    pos = np.array([a.step(c) for c in cmds])
    neg = np.array([b.step(-c) for c in cmds])
    np.testing.assert_array_equal(neg, -pos)
    # the same through the batch path
    c, d = TvcActuator(params), TvcActuator(params)
    out_p = c.run(cmds)
    out_n = d.run(-cmds)
    for xp, xn in zip(out_p, out_n):
        np.testing.assert_array_equal(np.array(xn), -np.array(xp))


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("sign", (1.0, -1.0))
def test_negative_rate_limit_holds_acceleration_at_zero(params, sign, path):
    """On the rate limit β̇ = ±R with the law pushing beyond it, β̈ is reported as 0."""
    act = TvcActuator(params)
    beta, beta_dot, beta_ddot = _advance(act, sign * 5.0 * DEG, 200, path)
    rate = params.rate_limit_radps
    on = beta_dot == sign * rate
    assert on.sum() > 100
    assert np.all(beta_ddot[on] == 0.0)


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("sign", (1.0, -1.0))
def test_command_just_beyond_a_stop_rests_on_it_with_zero_acceleration(params, sign, path):
    """u = ±(P + 5e-5 rad): the unlimited law would push with ω²·5e-5 = 0.5 rad/s² into the
    stop; on the stop the nozzle rests: (±P, 0, 0)."""
    act = TvcActuator(params)
    p = params.position_limit_rad
    beta, beta_dot, beta_ddot = _advance(act, sign * (p + 5e-5), 3000, path)
    assert (beta[-1], beta_dot[-1], beta_ddot[-1]) == (sign * p, 0.0, 0.0)
    held = np.abs(beta) == p
    assert held.sum() > 1000 and np.all(beta_dot[held] * sign <= 0.0)
    assert np.all(beta_ddot[held] == 0.0)


@pytest.mark.parametrize("path", PATHS)
@pytest.mark.parametrize("sign", (1.0, -1.0))
def test_leaving_the_negative_stop_moves_away_from_it(params, sign, path):
    act = TvcActuator(params)
    p = params.position_limit_rad
    _advance(act, sign * 1.0, 1500, path)
    assert act.state == (sign * p, 0.0, 0.0)
    b, r, _ = act.step(0.0)
    assert sign * r < 0.0 and sign * b < p     # first step back already moves inwards


def _one(act, u, path):
    return act.step(u) if path == "step" else tuple(v[0] for v in act.run([u])[:3])


@pytest.mark.parametrize("path", PATHS)
def test_a_linear_step_ending_exactly_on_the_rate_limit_is_not_limited(params, path):
    """Step 2 of the law acts only for |β̇'| > R. The smallest command whose first step from
    rest ends at β̇ = R exactly is a linear step: β equals the exact continuous response."""
    rate, dt = params.rate_limit_radps, params.dt_s
    _, rd = analytic_step(1.0, dt, params.wn_radps, params.zeta)
    u = rate / rd
    act = TvcActuator(params)
    cands = []
    x = u
    for _ in range(40):
        x = math.nextafter(x, 0.0)
    for _ in range(80):
        act.reset()
        b, r, a = _one(act, x, path)
        if r == rate:
            cands.append((x, b))
        x = math.nextafter(x, 1.0)
    assert cands, "no command within 40 ulps ends at the rate limit"
    x, b = cands[0]
    b_ref, _ = analytic_step(x, dt, params.wn_radps, params.zeta)
    assert b == pytest.approx(b_ref, rel=1e-9)
    # the trapezoid of the limited step would give dt/2·R: 3 % off
    assert abs(b - 0.5 * dt * rate) > 0.01 * b_ref
    # mirrored: the command −x ends exactly at −R, also unlimited
    act.reset()
    b, r, _ = _one(act, -x, path)
    assert r == -rate and b == pytest.approx(-b_ref, rel=1e-9)


@pytest.mark.parametrize("path", PATHS)
def test_arriving_exactly_on_the_stop_keeps_the_rate(params, path):
    """Step 3 acts only for β' > P: a rate-limited step that lands exactly on P keeps β̇ = R
    (β̈ held at 0); the next step then stops it."""
    pos, rate, dt = params.position_limit_rad, params.rate_limit_radps, params.dt_s
    act = TvcActuator(params)
    b0 = pos - 0.5 * dt * rate
    for _ in range(20):
        b0 = math.nextafter(b0, 0.0)
    found = None
    for _ in range(40):
        act.reset(b0)
        out = _one(act, 1.0, path)       # huge command: linear β̇ ≫ R → rate-limited
        if out[0] == pos:
            found = out
            break
        b0 = math.nextafter(b0, 1.0)
    assert found is not None, "no start position within 20 ulps lands on the stop"
    assert found == (pos, rate, 0.0)
    assert _one(act, 1.0, path) == (pos, 0.0, 0.0)
    # mirrored
    act.reset(-b0)
    assert _one(act, -1.0, path) == (-pos, -rate, 0.0)


@pytest.mark.parametrize("path", PATHS)
def test_odd_on_the_rate_limit_with_the_law_pulling_back(params, path):
    """Steps that end on the rate limit with |β̈| < 1 rad/s² pointing back inside (found by a
    sweep of the command; e.g. u = 0.5077°, step 18): β̈ is reported (not held at 0), and −u
    gives exactly the mirrored values."""
    rate = params.rate_limit_radps
    seen = 0
    for u in np.linspace(0.5 * DEG, 0.6 * DEG, 40):
        a, b = TvcActuator(params), TvcActuator(params)
        pos = np.array(_advance(a, u, 40, path))
        neg = np.array(_advance(b, -u, 40, path))
        np.testing.assert_array_equal(neg, -pos)
        pulled = (pos[1] == rate) & (pos[2] < 0.0) & (pos[2] > -1.0)
        seen += int(pulled.sum())
    assert seen >= 5

