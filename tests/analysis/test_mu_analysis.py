"""Mixed-μ upper bound (vega_analysis.mu_analysis) against known answers.

* μ of matrices with closed-form answers: one full complex block (σ̄), block-diagonal and
  diagonal matrices (the largest block's μ; a real scalar only where its entry is real), and
  rank-one matrices, whose mixed μ is Young, Newlin & Doyle's (1995) / Chen, Fan & Nett's (1994)
  formula μ(a bᵀ) = min_x Σ_real |Re c_i + x Im c_i| + √(1 + x²) Σ_complex |c_i|, c_i = a_i b_i
  (Σ|c_i| with aligned real c_i, 0 with a common non-real phase), and for which the (D, G)
  bound is exact; the certificate reproduces ab13md's own bound from its scalings;
* real-parametric loops whose destabilising parameter is known analytically, through the
  whole LFT chain (fit, factorisation, interconnection, μ): k(1 + hδ)/(s + 1)³ under unity
  feedback (unstable at k(1 + hδ) = 8, at ω = √3: μ_peak = k h/(8 − k)) and a second-order
  plant with uncertain damping (unstable at ζ(1 + hδ) = 0, at ω0√(1 + k): μ_peak = h);
* the delay disc holds every delay of the range;
* the LFT of the shipped table's loop at 50 s: det(I − MΔ) equals the ratio of return
  differences of the fitted plant (exact algebra), fresh plants of the set stay within the
  cover, the modal rescaling leaves the plant's transfer function unchanged;
* the shipped table at 50 s: the centre loop is stable, μ is finite and positive, and shrinking
  the box shrinks the bound.
"""

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from vega_loops import margins as M
from vega_analysis import mu_analysis as MU
from vega_gnc.controller_table import default_table_path, load_controller_table

RNG_SEED = 20240611


def _rank_one_mu(c, real):
    """Exact mixed μ of a rank-one matrix with entries c_i = a_i b_i on the diagonal of b a
    (Young, Newlin & Doyle 1995): min over x of a convex piecewise-smooth function."""
    c = np.asarray(c, dtype=complex)
    real = np.asarray(real, dtype=bool)

    def phi(x):
        return (np.sum(np.abs(c[real].real + x * c[real].imag))
                + math.sqrt(1.0 + x * x) * np.sum(np.abs(c[~real])))

    xs = np.concatenate([[0.0], -c[real].real / np.where(c[real].imag == 0, np.inf,
                                                         c[real].imag)])
    best = min(phi(x) for x in xs)          # the kinks (the minimum of the real part)
    res = minimize_scalar(phi, bounds=(-1e3, 1e3), method="bounded",
                          options={"xatol": 1e-10})
    return min(best, float(res.fun))


# ------------------------------------------------------------------- μ of a matrix, textbook
def test_one_full_complex_block_is_the_largest_singular_value():
    rng = np.random.default_rng(RNG_SEED)
    Z = rng.standard_normal((4, 4)) + 1j * rng.standard_normal((4, 4))
    mu, _ = MU.mu_upper_bound(Z, [4], [2])
    assert mu == pytest.approx(np.linalg.norm(Z, 2), rel=1e-12)


def test_block_diagonal_complex_blocks_give_the_largest_block():
    rng = np.random.default_rng(RNG_SEED + 1)
    Z1 = rng.standard_normal((2, 2)) + 1j * rng.standard_normal((2, 2))
    Z2 = 3.0 * (rng.standard_normal((2, 2)) + 1j * rng.standard_normal((2, 2)))
    Z = np.zeros((4, 4), complex)
    Z[:2, :2], Z[2:, 2:] = Z1, Z2
    mu, info = MU.mu_upper_bound(Z, [2, 2], [2, 2])
    exact = max(np.linalg.norm(Z1, 2), np.linalg.norm(Z2, 2))
    assert exact * (1 - 1e-9) <= mu <= exact * 1.01
    assert not info["fallback"]


def test_diagonal_matrix_complex_and_real_scalars():
    m = np.array([0.5, -2.0 + 0j, 1.0 + 1.5j, 0.3j])
    # complex scalars: det(I − MΔ) = Π(1 − m_i δ_i) vanishes first at |δ| = 1/max|m_i|
    mu_c, _ = MU.mu_upper_bound(np.diag(m), [1] * 4, [2] * 4)
    assert mu_c == pytest.approx(np.abs(m).max(), rel=1e-3)
    assert mu_c >= np.abs(m).max() * (1 - 1e-9)
    # real scalars: only a real m_i can be cancelled by a real δ_i: μ = 2 (not |1 + 1.5j|)
    mu_r, _ = MU.mu_upper_bound(np.diag(m), [1] * 4, [1] * 4)
    assert 2.0 * (1 - 1e-9) <= mu_r <= 2.0 * 1.01


@pytest.mark.parametrize("case", ["aligned", "common_phase", "mixed", "random_real"])
def test_rank_one_matrices_match_the_closed_form(case):
    rng = np.random.default_rng(RNG_SEED + 7)
    n = 5
    a = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    b = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    real = np.ones(n, dtype=bool)
    if case == "aligned":                  # c_i = a_i b_i real positive: μ = Σ|c_i|
        # (real vectors: with rounding-level imaginary parts the real μ of a rank-one matrix
        # is, correctly, discontinuous and the closed form drops far below Σ|c_i|)
        a, b = a.real, np.abs(b) * np.sign(a.real)
    elif case == "common_phase":           # c_i all of phase 60°: no real δ reaches 1
        b = np.abs(b) * np.exp(1j * (np.pi / 3 - np.angle(a)))
    elif case == "mixed":
        real[-2:] = False
    Z = np.outer(a, b)
    c = a * b
    exact = _rank_one_mu(c, real)
    if case == "aligned":
        assert exact == pytest.approx(np.sum(np.abs(c)), rel=1e-12)
    if case == "common_phase":
        assert exact == pytest.approx(0.0, abs=1e-12)
    it = np.where(real, 1, 2)
    # ab13md's scalings on the barely perturbed matrix: the (D, G) bound is exact for rank one
    mu, _ = MU.mu_upper_bound(Z, [1] * n, it, regularise=1e-4)
    assert mu >= exact - 1e-9 * np.sum(np.abs(c))           # an upper bound …
    assert mu <= exact * 1.002 + 0.002 * np.sum(np.abs(c))  # … and tight
    # the default regularisation (for ab13md's run time on the loop matrices) stays an upper
    # bound and alone costs tightness (measured 12 % on the aligned case, the worst of the
    # four); the whole-matrix call takes it back
    mu_r, _ = MU.mu_upper_bound(Z, [1] * n, it, whole=False)
    assert exact - 1e-9 * np.sum(np.abs(c)) <= mu_r <= exact * 1.15 + 0.15 * np.sum(np.abs(c))
    mu_d, _ = MU.mu_upper_bound(Z, [1] * n, it)
    assert exact - 1e-9 * np.sum(np.abs(c)) <= mu_d <= min(mu_r, exact * 1.002
                                                           + 0.002 * np.sum(np.abs(c)))


def test_certificate_reproduces_ab13md_from_its_own_scalings():
    from slycot import ab13md

    rng = np.random.default_rng(RNG_SEED + 3)
    Z = rng.standard_normal((6, 6)) + 1j * rng.standard_normal((6, 6))
    nb, it = np.ones(6, int), np.array([1, 1, 1, 1, 2, 2])
    bound, d, g, _ = ab13md(Z, nb, it)
    assert MU.mu_certificate(Z, d, g) == pytest.approx(bound, rel=1e-6)
    # the regularised, reduced, polished bound is a certificate of Z itself, no looser
    mu, info = MU.mu_upper_bound(Z, nb, it)
    assert mu <= info["certified"] + 1e-12
    assert bound * 0.97 <= mu <= bound * 1.03
    # a scaling that is not optimal certifies a larger value
    assert MU.mu_certificate(Z, d * np.r_[1.5, 1, 1, 1, 1, 1], g) > bound * (1 + 1e-6)


def test_delay_disc_holds_every_delay_of_the_range():
    h = 0.010
    w = np.geomspace(0.01, 500.0, 400)
    dts = np.linspace(-h, h, 41)
    gap = np.abs(np.exp(-1j * np.outer(w, dts)) - 1.0).max(axis=1)
    wt = MU.delay_weight(w, h)
    assert np.all(gap <= wt + 1e-12)
    small = w * h <= math.pi
    assert np.allclose(gap[small], wt[small], rtol=1e-9)     # the disc is the tightest


# ------------------------------------------------------- real-parametric loops, known answers
def _loop_mu(S_of, F, w, k=1):
    """μ of a real-parametric SISO loop through the module's LFT chain (no delay range)."""
    S0, lin, quad = MU.axis_fit(S_of, k, [False] * k)
    n = S0.shape[1] - 1
    lft = MU.build_lft(S0, lin, {}, tuple(f"p{i}" for i in range(k)), n,
                       (np.eye(S0.shape[0]), np.eye(S0.shape[1])), rank_tol=1e-9)
    Fw = np.broadcast_to(np.asarray(F, complex), (w.size, S0.shape[0] - n))
    Ms = MU.interconnection(lft, Fw, w, np.zeros(w.size))
    nb, it = np.ones(lft.n_scalars + 1, int), np.r_[np.ones(lft.n_scalars, int), 2]
    return lft, np.array([MU.mu_upper_bound(Z, nb, it)[0] for Z in Ms])


def test_third_order_loop_gain_uncertainty_gives_k_h_over_8_minus_k():
    # G = k(1 + hδ)/(s + 1)³, u = −y: s³ + 3s² + 3s + 1 + k(1 + hδ) is unstable from
    # k(1 + hδ) = 8 (Routh), with poles ±j√3: δ* = (8/k − 1)/h, μ_peak = k h/(8 − k) at √3
    k, h = 4.0, 0.5

    def S_of(d):
        S = np.zeros((4, 4))
        S[:3, :3] = [[0, 1, 0], [0, 0, 1], [-1, -3, -3]]
        S[2, 3] = k * (1 + h * d[0])
        S[3, 0] = 1.0
        return S

    w = np.array([0.3, 1.0, math.sqrt(3.0), 3.0, 10.0])
    lft, mu = _loop_mu(S_of, [-1.0], w)
    assert lft.n_scalars == 1
    exact = k * h / (8 - k)
    assert exact * (1 - 1e-9) <= mu[2] <= exact * 1.01
    assert np.argmax(mu) == 2 and np.all(np.delete(mu, 2) < 0.05)
    # the destabilising size 1/μ is the Routh one: stable just inside, unstable at it
    for d, unstable in ((0.99 / mu[2], False), (1.0 / exact * 1.001, True)):
        A = S_of([d])[:3, :3] - np.outer(S_of([d])[:3, 3], S_of([d])[3, :3])
        assert (np.linalg.eigvals(A).real.max() > 0) == unstable


def test_second_order_damping_uncertainty_gives_h():
    # ẍ = −ω0² x − 2ζ(1 + hδ)ω0 ẋ + ω0² u, u = −k y: s² + 2ζ(1 + hδ)ω0 s + ω0²(1 + k) loses its
    # damping at δ = −1/h, on the axis at ω0√(1 + k): μ_peak = h there
    w0, zeta, k, h = 5.0, 0.05, 1.5, 0.7

    def S_of(d):
        S = np.zeros((3, 3))
        S[:2, :2] = [[0, 1], [-w0 ** 2, -2 * zeta * (1 + h * d[0]) * w0]]
        S[1, 2] = w0 ** 2
        S[2, 0] = 1.0
        return S

    wc = w0 * math.sqrt(1 + k)
    w = np.array([0.5 * wc, 0.95 * wc, wc, 1.05 * wc, 2 * wc])
    _, mu = _loop_mu(S_of, [-k], w)
    assert h * (1 - 1e-9) <= mu[2] <= h * 1.01
    assert np.argmax(mu) == 2 and mu[0] < 0.05 and mu[-1] < 0.05


# ------------------------------------------------------------- the shipped table at max-Q
@pytest.fixture(scope="module")
def context():
    from vega_model.parameters import default_context

    return default_context()


@pytest.fixture(scope="module")
def table():
    return load_controller_table(default_table_path())


@pytest.fixture(scope="module")
def problem(table, context):
    return MU.mu_problem(table, context, 50.0)


@pytest.fixture(scope="module")
def validation(problem):
    return MU.validate(problem)


def _loop_of(S, n, F, w):
    G = M.ss_response(S[:n, :n], S[:n, n:], S[n:, :n], np.zeros((S.shape[0] - n, 1)), w)
    return -np.sum(F * G[:, :, 0], axis=1)


def test_lft_determinant_is_the_ratio_of_return_differences(problem):
    # det(I − MΔ) = det(jωI − A_fit)(1 + e^{−jωΔτ} L_fit − ε δ_e) / (det(jωI − A0)(1 + L0)):
    # the interconnection is the fitted plant's loop, delay disc and cover, exactly
    lft, n = problem.lft, problem.lft.n
    rng = np.random.default_rng(RNG_SEED + 11)
    w = np.array([0.3, 2.0, 24.0, 32.5, 74.0, 150.0])
    F = problem.controller_row(w)
    eps = 0.05 * np.ones(w.size)
    Ms = MU.interconnection(lft, F, w, MU.delay_weight(w, problem.box.delay_half_s), eps)
    L0 = _loop_of(lft.S0, n, F, w)
    for _ in range(3):
        delta = rng.uniform(-1, 1, len(problem.box.names))
        dtau = rng.uniform(-1, 1) * problem.box.delay_half_s
        de = 0.7 * np.exp(1j * rng.uniform(0, 2 * np.pi))
        Sf = lft.matrix(delta)
        Lf = _loop_of(Sf, n, F, w)
        for k, wk in enumerate(w):
            dc = (np.exp(-1j * wk * dtau) - 1.0) / MU.delay_weight(wk, problem.box.delay_half_s)
            assert abs(dc) <= 1.0 + 1e-12
            Delta = np.diag(np.r_[delta[lft.param], dc, de])
            lhs = np.linalg.det(np.eye(Ms.shape[1]) - Ms[k] @ Delta)
            jw = 1j * wk * np.eye(n)
            rhs = (np.linalg.det(jw - Sf[:n, :n]) * (1 + np.exp(-1j * wk * dtau) * Lf[k]
                                                    - eps[k] * de)
                   / (np.linalg.det(jw - lft.S0[:n, :n]) * (1 + L0[k])))
            # ratios of 10×10 determinants of lightly damped matrices: relative rounding
            # measured up to 3e-7
            assert lhs == pytest.approx(rhs, rel=2e-6)


@pytest.mark.slow
def test_fresh_plants_of_the_set_stay_within_the_stated_fit_error(problem, validation):
    w = problem.w_radps
    F = problem.controller_row(w)
    err, rel = validation.errors(F, w)
    stated, eps = float(rel.max()), validation.cover(problem.controller_row, w)
    assert 0.0 < stated < 0.5                      # the fit is worth its name at max-Q
    rng = np.random.default_rng(RNG_SEED + 13)     # apart from the validation sample
    n = problem.lft.n
    worst = 0.0
    for _ in range(40):
        delta = rng.choice([-1.0, 1.0], len(problem.box.names)) * rng.uniform(0.6, 1.0)
        Lt = _loop_of(problem.plant(delta), n, F, w)
        Lf = _loop_of(problem.lft.matrix(delta), n, F, w)
        assert np.all(np.abs(Lt - Lf) <= eps)       # inside the cover at every frequency
        worst = max(worst, float(np.max(np.abs(Lt - Lf) / np.abs(1 + Lt))))
    assert worst <= MU.COVER_FACTOR * stated


def test_modal_rescaling_leaves_the_plant_unchanged(problem, context, table):
    rng = np.random.default_rng(RNG_SEED + 17)
    w = np.array([0.5, 20.0, 33.0, 75.0])
    for _ in range(3):
        dev = problem.box.deviations(rng.uniform(-1, 1, len(problem.box.names)))
        S1 = MU.plant_matrix(context, 50.0, dev, table.input_names, modal_scaling=True)
        S2 = MU.plant_matrix(context, 50.0, dev, table.input_names, modal_scaling=False)
        n = problem.lft.n
        G1 = M.ss_response(S1[:n, :n], S1[:n, n:], S1[n:, :n], np.zeros((4, 1)), w)
        G2 = M.ss_response(S2[:n, :n], S2[:n, n:], S2[n:, :n], np.zeros((4, 1)), w)
        assert np.allclose(G1, G2, rtol=1e-9, atol=1e-14)
        assert not np.allclose(S1, S2)              # the coordinates did change


@pytest.mark.slow
def test_shipped_table_at_max_q(table, context):
    w = np.array([0.3, 6.7, 24.75, 32.47, 73.9])
    res = MU.mu_at_time(table, context, 50.0, w_radps=w, n_repass=2)
    assert res["centre_stable"] and res["centre_max_abs_eig"] < 1.0
    assert np.all(np.isfinite(res["mu_upper"])) and 0.0 < res["mu_peak"] < 10.0
    assert res["robust_margin"] == pytest.approx(1.0 / res["mu_peak"])
    assert res["n_fallback"] == 0 and res["n_blocks"] == res["n_real_scalars"] + 2
    assert sum(res["ranks"].values()) == res["n_real_scalars"]
    assert np.all(res["mu_upper"] <= res["mu_ab13md"] + 1e-12)
    assert 0.0 < res["fit_error"]["loop_rel"] < 0.5 and res["aliasing_centre_rel"] < 0.05
    # half the box: a smaller bound at every frequency, about half of it where the real
    # parameters dominate (the delay disc and the cover shrink too, not linearly)
    half = MU.mu_at_time(table, context, 50.0, box_scale=0.5, w_radps=w, n_repass=2)
    assert np.all(half["mu_upper"] < res["mu_upper"])
    assert 0.2 < half["mu_peak"] / res["mu_peak"] < 0.8


def test_box_scale_refuses_unphysical_deviations(context):
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    with pytest.raises(ValueError, match="psi_mode_2"):
        MU.parameter_box(uset, 2.0)                 # −50 % × 2 = −100 %
