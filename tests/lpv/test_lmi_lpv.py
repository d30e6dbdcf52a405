"""Rate-bounded LPV synthesis on a small gridded plant (docs/LPV_SYNTHESIS.md §2–§5).

The plant: a position loop whose stiffness a(ρ) = −1 + 0.8ρ + 0.2ρ² turns it unstable as ρ
grows and whose control gain b(ρ) = 1 + 0.25ρ varies, with a first-order weight on position,
a control-effort output and noisy position measurement; ρ ∈ [1, 3] on five grid points.
Checked: γ ordering (frozen-point LTI γ ≤ rate-bounded ≤ quadratic; X constant ≥ full),
the closed-loop certificate at the grid points, at a 4× denser grid and at each rate vertex,
the affine ρ̇-dependence of the controller, and the input validation.
"""

import control
import numpy as np
import pytest
import cvxpy  # noqa: F401 - pinned dependency: a broken install fails, never skips

from vega_lpv.certificate import certificate_check, closed_loop, hinf_norm
from vega_lpv.gridded_plant import GriddedPlant, PlantPoint
from vega_lpv.lpv_synthesis import synthesize

# every test here shares a module fixture that takes seconds (a solve or a flight)
pytestmark = pytest.mark.slow

RHO = np.linspace(1.0, 3.0, 5)
RATES = (-0.5, 0.5)
POSITIVE_RATES = (0.1, 0.6)          # all-positive box as in the thesis: ρ̇ = 0 is no vertex
TOL = 1e-3                           # relative tolerance on γ comparisons (solver accuracy)


def plant_at(rho):
    """Generalised plant at ρ: w = (force disturbance, sensor noise), e = (W x1, 0.1 u)."""
    a = -1.0 + 0.8 * rho + 0.2 * rho ** 2
    b = 1.0 + 0.25 * rho
    A = np.array([[0.0, 1.0, 0.0],
                  [a, -0.4, 0.0],
                  [0.5, 0.0, -0.5]])
    B = np.array([[0.0, 0.0, 0.0],
                  [b, 0.0, b],
                  [0.0, 0.0, 0.0]])
    C = np.array([[0.0, 0.0, 2.0],
                  [0.0, 0.0, 0.0],
                  [1.0, 0.0, 0.0]])
    D = np.array([[0.0, 0.0, 0.0],
                  [0.0, 0.0, 0.1],
                  [0.0, 0.1, 0.0]])
    return PlantPoint(A, B, C, D, n_w=2, n_u=1, n_e=2, n_y=1)


@pytest.fixture(scope="module")
def plant():
    return GriddedPlant.from_points(RHO, [plant_at(r) for r in RHO])


@pytest.fixture(scope="module")
def rate_bounded(plant):
    return synthesize(plant, rate_bounds=RATES)


@pytest.fixture(scope="module")
def quadratic(plant):
    return synthesize(plant, rate_bounds=None)


@pytest.fixture(scope="module")
def x_constant(plant):
    return synthesize(plant, rate_bounds=RATES, x_constant=True)


def _dense(rho, factor=4):
    return np.linspace(rho[0], rho[-1], factor * (rho.size - 1) + 1)


def test_rate_bounded_is_no_worse_than_quadratic(rate_bounded, quadratic):
    assert rate_bounded.gamma_min <= quadratic.gamma_min * (1.0 + TOL)
    assert quadratic.rate_vertices == () and rate_bounded.rate_vertices == RATES
    assert len(quadratic.X_k) == 1 and len(quadratic.Y_k) == 1
    assert len(rate_bounded.X_k) == 3 and len(rate_bounded.Y_k) == 3


def test_frozen_point_gamma_is_a_lower_bound(plant, rate_bounded):
    for i in range(plant.n_grid):
        p = plant.point(i)
        _, _, gamma_i, _ = control.hinfsyn(control.ss(p.A, p.B, p.C, p.D), p.n_y, p.n_u)
        assert gamma_i <= rate_bounded.gamma_min * (1.0 + TOL)


@pytest.mark.parametrize("variant", ["rate_bounded", "quadratic", "x_constant"])
def test_certificate_on_grid_and_dense_grid(request, plant, variant):
    result = request.getfixturevalue(variant)
    assert result.certificate_max_eig < 0.0
    assert np.all(certificate_check(plant, result, RHO, RATES) < 0.0)
    assert np.all(certificate_check(plant_at, result, _dense(RHO), RATES) < 0.0)
    # the flight form: grid controllers interpolated linearly in ρ
    assert np.all(certificate_check(plant_at, result, _dense(RHO), RATES,
                                    controller="interpolated") < 0.0)


def test_frozen_closed_loops_meet_gamma(rate_bounded):
    for rho in _dense(RHO):
        for rate in RATES:
            K = rate_bounded.controller(rho, rate, plant_point=plant_at(rho))
            A_cl, B_cl, C_cl, D_cl = closed_loop(plant_at(rho), K)
            assert hinf_norm(A_cl, B_cl, C_cl, D_cl) <= rate_bounded.gamma * (1.0 + TOL)


def test_all_positive_rate_box(plant):
    result = synthesize(plant, rate_bounds=POSITIVE_RATES)
    assert result.rate_vertices == POSITIVE_RATES
    assert np.all(certificate_check(plant_at, result, _dense(RHO), POSITIVE_RATES) < 0.0)


def test_controller_is_affine_in_rate(rate_bounded):
    rho = RHO[2]
    K_lo, K_hi = (rate_bounded.controller(rho, r) for r in RATES)
    K_mid = rate_bounded.controller(rho, 0.5 * sum(RATES))
    for lo, hi, mid in zip(K_lo, K_hi, K_mid):
        np.testing.assert_allclose(mid, 0.5 * (lo + hi), rtol=1e-9, atol=1e-9 * np.abs(lo).max())
    assert not np.allclose(K_lo[0], K_hi[0])                   # A_K depends on ρ̇ …
    for lo, hi in zip(K_lo[1:], K_hi[1:]):                      # … B_K, C_K, D_K do not
        np.testing.assert_allclose(lo, hi, rtol=1e-12, atol=1e-12)


def test_x_constant_controller_ignores_rate(rate_bounded, x_constant):
    assert x_constant.gamma_min >= rate_bounded.gamma_min * (1.0 - TOL)
    assert len(x_constant.X_k) == 1 and len(x_constant.Y_k) == 3
    for rho in _dense(RHO):
        K_lo, K_hi = (x_constant.controller(rho, r) for r in RATES)
        for lo, hi in zip(K_lo, K_hi):
            np.testing.assert_array_equal(lo, hi)


def test_interpolated_controller_matches_grid_values(rate_bounded):
    K_grid = rate_bounded.controller(RHO[1], RATES[1])
    K_exact = rate_bounded.controller(RHO[1], RATES[1], plant_point=plant_at(RHO[1]))
    for a, b in zip(K_grid, K_exact):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10)
    mid = 0.5 * (RHO[1] + RHO[2])
    K_mid = rate_bounded.controller(mid, RATES[1])
    K_next = rate_bounded.controller(RHO[2], RATES[1])
    for a, b, m in zip(K_grid, K_next, K_mid):
        np.testing.assert_allclose(m, 0.5 * (a + b), rtol=1e-12, atol=1e-12)


def _one_line_value_error(call):
    with pytest.raises(ValueError) as info:
        call()
    assert "\n" not in str(info.value) and str(info.value)


def test_malformed_inputs_raise_one_line_value_errors(plant, rate_bounded):
    A, B, C, D = plant.A, plant.B, plant.C, plant.D
    sizes = (plant.n_w, plant.n_u, plant.n_e, plant.n_y)
    _one_line_value_error(lambda: GriddedPlant(RHO, A, B[:, :, :-1], C, D, *sizes))
    _one_line_value_error(lambda: GriddedPlant(RHO[:-1], A, B, C, D, *sizes))
    _one_line_value_error(lambda: GriddedPlant(RHO[::-1], A, B, C, D, *sizes))
    _one_line_value_error(lambda: GriddedPlant(np.r_[RHO[:2], RHO[1:4]], A, B, C, D, *sizes))
    _one_line_value_error(lambda: GriddedPlant(RHO, A, B, C, D, 2, 1, 2, 0))
    nan_A = A.copy()
    nan_A[0, 0, 0] = np.nan
    _one_line_value_error(lambda: GriddedPlant(RHO, nan_A, B, C, D, *sizes))
    no_D12 = D.copy()
    no_D12[:, :2, 2] = 0.0                                      # D12 = 0: rank deficient
    _one_line_value_error(lambda: synthesize(GriddedPlant(RHO, A, B, C, no_D12, *sizes)))
    no_D21 = D.copy()
    no_D21[3, 2, :2] = 0.0                                      # D21 = 0 at one grid point
    _one_line_value_error(lambda: synthesize(GriddedPlant(RHO, A, B, C, no_D21, *sizes)))
    _one_line_value_error(lambda: synthesize(plant, rate_bounds=(1.0, -1.0)))
    _one_line_value_error(lambda: synthesize(plant, basis="cubic"))
    _one_line_value_error(lambda: synthesize(plant, backoff=0.5))
    two_points = GriddedPlant(RHO[:2], A[:2], B[:2], C[:2], D[:2], *sizes)
    _one_line_value_error(lambda: synthesize(two_points, rate_bounds=RATES))
    _one_line_value_error(lambda: certificate_check(plant, rate_bounded, [1.7], RATES))
    _one_line_value_error(lambda: certificate_check(plant, rate_bounded, RHO, RATES, "spline"))


def test_plant_rate_term_enters_lmis_controller_and_certificate(plant):
    """A plant ẋ = (A(ρ) + ρ̇ N) x + … (the term a ρ-dependent state transformation adds):
    the synthesis imposes it at the rate vertices, and its certificate holds for that plant,
    not for the plant without the term whose certificate the plain synthesis passes."""
    N = np.zeros((3, 3))
    N[1, 1] = -0.8                       # ρ̇ = 0.5 adds damping 0.4, ρ̇ = −0.5 removes it all
    with_term = GriddedPlant(plant.rho, plant.A, plant.B, plant.C, plant.D, plant.n_w,
                             plant.n_u, plant.n_e, plant.n_y, N=np.array([N] * plant.n_grid))
    result = synthesize(with_term, rate_bounds=RATES)
    assert result.certificate_max_eig < 0.0 and len(result.rate_A) == plant.n_grid
    worst = certificate_check(plant_at, result, _dense(RHO), RATES, rate_term=lambda rho: N)
    assert np.max(worst) < 0.0
    # the plain design (term left out) is not certified for the plant with the term
    plain = synthesize(plant, rate_bounds=RATES)
    assert np.max(certificate_check(plant_at, plain, RHO, RATES, rate_term=lambda rho: N)) > 0.0
    assert result.gamma > plain.gamma
    # the controller depends on the term: at ρ̇ = 0 it is the plain plant's reconstruction
    K0 = result.controller(RHO[2], 0.0)
    K0_point = result.controller(RHO[2], 0.0, plant_point=plant_at(RHO[2]), rate_term=N)
    for a, b in zip(K0, K0_point):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    K_hi = result.controller(RHO[2], 0.5)
    K_hi_no_term = result.controller(RHO[2], 0.5, plant_point=plant_at(RHO[2]))
    assert not np.allclose(K_hi[0], K_hi_no_term[0])
    with pytest.raises(ValueError, match="N has shape"):
        GriddedPlant(plant.rho, plant.A, plant.B, plant.C, plant.D, plant.n_w, plant.n_u,
                     plant.n_e, plant.n_y, N=np.zeros((plant.n_grid, 2, 2)))
