"""The nonlinear model's Jacobian at the operating point equals the linear model.

Thesis Table 2.2: all states and inputs zero. Central finite differences of
``nonlinear_derivatives`` / ``nonlinear_outputs`` must reproduce every non-zero entry of
``linear_model``'s A, B, C, D to a relative error below 1e-6, and its exact zeros to
round-off, at seven flight times — including times between flight-condition table rows.
"""

import numpy as np
import pytest

from vega_model.dynamics import linear_model, nonlinear_derivatives, nonlinear_outputs
from vega_model.parameters import model_parameters

# Steps: every perturbation that moves α does so by ~1e-7 rad (the crossflow term
# sin α|sin α| is odd, so a central difference has an O(h) error there): θ, θ̇, β 1e-7;
# ż and v_w 1e-7·V; z, modal coordinates and β̈ 1e-5.


def _steps(v_mps):
    hv = 1e-7 * v_mps
    return (np.array([1e-7, 1e-7, 1e-4, hv, 1e-5, 1e-5, 1e-5, 1e-5]),
            np.array([1e-7, 1e-5, hv]))

TIMES_S = (5.0, 20.0, 35.0, 47.13, 60.0, 75.0, 95.05)


def _central_jacobian(f, n, h):
    cols = []
    for i in range(n):
        e = np.zeros(n)
        e[i] = h[i]
        cols.append((f(e) - f(-e)) / (2.0 * h[i]))
    return np.array(cols).T


def _assert_equal_jacobian(name, analytic, numeric, t):
    nonzero = analytic != 0.0
    rel = np.abs(numeric[nonzero] - analytic[nonzero]) / np.abs(analytic[nonzero])
    assert rel.max() < 1e-6, f"{name} at t={t}: max relative error {rel.max():.2e}"
    scale = np.abs(analytic).max()
    assert np.abs(numeric[~nonzero]).max(initial=0.0) <= 1e-9 * scale, (
        f"{name} at t={t}: entry that should be zero is not")


@pytest.mark.parametrize("t", TIMES_S)
def test_jacobian_equals_linear_model(t):
    p = model_parameters(t)
    A, B, C, D = linear_model(p)
    u0 = np.zeros(3)
    x0 = np.zeros(8)
    H_X, H_U = _steps(p.v_mps)
    An = _central_jacobian(lambda dx: nonlinear_derivatives(p, x0 + dx, u0), 8, H_X)
    Bn = _central_jacobian(lambda du: nonlinear_derivatives(p, x0, u0 + du), 3, H_U)
    Cn = _central_jacobian(lambda dx: nonlinear_outputs(p, x0 + dx, u0), 8, H_X)
    Dn = _central_jacobian(lambda du: nonlinear_outputs(p, x0, u0 + du), 3, H_U)
    for name, analytic, numeric in (("A", A, An), ("B", B, Bn), ("C", C, Cn), ("D", D, Dn)):
        _assert_equal_jacobian(name, analytic, numeric, t)


@pytest.mark.parametrize("t", (10.0, 50.0, 90.0))
def test_operating_point_is_an_equilibrium(t):
    p = model_parameters(t)
    xdot = nonlinear_derivatives(p, np.zeros(8), np.zeros(4))
    y = nonlinear_outputs(p, np.zeros(8), np.zeros(3))
    assert np.all(xdot == 0.0)
    assert np.all(y == 0.0)


def test_nozzle_rate_enters_only_quadratically():
    """β̇ has no linear effect (centripetal nozzle term ∝ β̇²), but a real nonlinear one."""
    p = model_parameters(50.0)
    x0 = np.zeros(8)
    f = lambda rate: nonlinear_derivatives(p, x0, [0.0, 0.0, 0.0, rate])  # noqa: E731
    h = 1e-4
    assert np.allclose((f(h) - f(-h)) / (2 * h), 0.0, atol=1e-12)
    # a large rate at a deflected nozzle changes the lateral force: −m_N l_N (−β̇² sin β)
    g = nonlinear_derivatives(p, x0, [0.05, 0.0, 0.0, 1.0]) - nonlinear_derivatives(
        p, x0, [0.05, 0.0, 0.0, 0.0])
    expected = p.nozzle_mass_kg * p.nozzle_lever_m * np.sin(0.05) / p.mass_kg
    assert g[3] == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("t", (0.5, 30.0, 47.13, 90.0))
def test_rk4_step_is_the_array_rk4_bit_for_bit(t):
    """The plant's plain-float RK4 step (NonlinearModel.rk4_step) gives exactly the numbers of
    the textbook RK4 on arrays of nonlinear_derivatives, over steps whose Mach leaves the
    segment of the parameters' own Mach (large drift rates and winds)."""
    from vega_model.dynamics import NonlinearModel

    p = model_parameters(t)
    model = NonlinearModel(p)
    rng = np.random.default_rng(int(t * 100))
    x = np.array([0.02, -0.01, 5.0, 3.0, 1e-3, -2e-3, 0.05, -0.04])
    h = 1e-3
    for _ in range(50):
        u = (float(rng.normal(0, 0.05)), float(rng.normal(0, 20.0)),
             float(rng.normal(0, 40.0)), float(rng.normal(0, 0.5)))
        k1 = nonlinear_derivatives(p, x, u)
        k2 = nonlinear_derivatives(p, x + 0.5 * h * k1, u)
        k3 = nonlinear_derivatives(p, x + 0.5 * h * k2, u)
        k4 = nonlinear_derivatives(p, x + h * k3, u)
        want = x + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
        got = model.rk4_step(tuple(x.tolist()), u, h)
        assert got == tuple(want.tolist())
        x = want
