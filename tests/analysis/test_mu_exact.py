"""The μ upper bound (vega_analysis.mu_analysis.mu_upper_bound) against exact and published μ.

* **Rank-one matrices, exact μ by an independent solver.** For M = a bᴴ and a structure of
  1×1 blocks (real or complex scalars), det(I − MΔ) = 1 − Σ δ_i c_i with c_i = conj(b_i) a_i.
  So μ(M) = max {t ≥ 0 : t ∈ S}, S = {Σ δ_i c_i : δ_i ∈ [−1, 1] real, |δ_i| ≤ 1 complex}: S is
  the zonogon spanned by the real blocks' c_i plus the disc of radius R = Σ_complex |c_i|, and
  the largest point of the positive real axis in it is found geometrically
  (:func:`rank_one_mu`, primal: a point of S, so a lower bound on μ that is attained). Its
  convex dual is the closed form of Young, Newlin & Doyle (*μ analysis with real parametric
  uncertainty*, CDC 1991) and Chen, Fan & Nett (*Structured singular values and stability
  analysis of uncertain polynomials*, Systems & Control Letters 1994):
  μ = min_θ (Σ_real |Re(e^{−jθ} c_i)| + R)/cos θ over |θ| < π/2 (:func:`rank_one_mu_dual`,
  an upper bound for every θ, minimised exactly). The two agree to 1e-12; all
  complex: Σ|c_i|; all real with real c_i: Σ|c_i|; all real with a common non-real phase: 0.
  For rank-one M the (D, G) bound equals μ (the same references), so the bound can be asked
  to be close.
* **Published examples.** Packard & Doyle's example of a gap between μ and its D-scaled upper
  bound (*The complex structured singular value*, Automatica 29(1), 1993), four complex
  scalars, M = U Vᴴ with orthonormal U, V: the D-scaled bound is 1 and μ ≈ 0.87 — as
  reproduced in the Xμ manual (National Instruments, 370760B-01, §3.7, pp. 108–109: "the D
  scale upper bound = 1", "mu is approximately 0.87", lower bound 0.864113). The SLICOT AB13MD
  documentation example (SLICOT-Reference doc/AB13MD.html, "Program Results"): a 6×6 matrix
  with two real scalars, a 2×2 complex block and two complex scalars, stated (D, G) upper
  bound 41.74753408; an upper bound, not μ itself.
"""

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from vega_analysis import mu_analysis as MU

RNG_SEED = 35
N_RANDOM = 120                 # 40 each: all real, all complex, mixed real/complex scalars
TIGHT = 0.10                   # the bound within 10 % of the exact μ on every rank-one case


# ---------------------------------------------------------------------- the exact solver
def rank_one_mu(c, real) -> float:
    """Exact μ of a rank-one matrix (entries c_i = conj(b_i) a_i), primal and geometric.

    The real blocks' segments δ_i c_i, δ_i ∈ [−1, 1], sum to a centrally symmetric convex
    polygon (a zonogon) whose vertices, counter-clockwise, are −Σg plus the partial sums of
    2g_k and then −2g_k, the generators g_k = ±c_k turned into the upper half-plane and
    sorted by angle. The complex blocks add a disc of radius R = Σ|c_i|. The largest real t
    in polygon ⊕ disc lies on its boundary: on an arc of radius R around a vertex
    (x + √(R² − y²)) or on an edge shifted outwards by R where it crosses the real axis."""
    c = np.asarray(c, dtype=complex)
    real = np.asarray(real, dtype=bool)
    R = float(np.sum(np.abs(c[~real])))
    g = c[real]
    g = g[g != 0]
    ang = np.angle(g)
    g = np.where((ang < 0) | (ang >= math.pi), -g, g)
    g = g[np.argsort(np.angle(g))]
    v = [-np.sum(g)]
    for gk in np.r_[g, -g]:
        v.append(v[-1] + 2.0 * gk)
    v = np.array(v[:-1]) if g.size else np.array([0j])
    cand = [p.real + math.sqrt(R * R - p.imag ** 2) for p in v if abs(p.imag) <= R]
    for k in range(v.size if v.size > 1 else 0):
        p, q = v[k], v[(k + 1) % v.size]
        e = q - p
        if e == 0:
            continue
        out = R * complex(e.imag, -e.real) / abs(e)        # outward normal × R
        p2, q2 = p + out, q + out
        if min(p2.imag, q2.imag) <= 0.0 <= max(p2.imag, q2.imag):
            if p2.imag == q2.imag:
                cand += [p2.real, q2.real]
            else:
                cand.append((p2 + p2.imag / (p2.imag - q2.imag) * (q2 - p2)).real)
    return max(cand)


def rank_one_mu_dual(c, real) -> float:
    """The closed form (Young, Newlin & Doyle 1991; Chen, Fan & Nett 1994) as the support
    function of the same set: every |θ| < π/2 gives the upper bound
    h(θ) = (Σ_real |Re(e^{−jθ} c_i)| + R)/cos θ, and its minimum is μ.

    Between two kinks (θ = arg c_i ± π/2) the signs s_i are fixed and h = A + B tan θ + R sec θ
    (A = Σ s_i Re c_i, B = Σ s_i Im c_i), convex, stationary at sin θ = −B/R where
    h = A + √(R² − B²); so the minimum is at a kink or at such a point."""
    c = np.asarray(c, dtype=complex)
    real = np.asarray(real, dtype=bool)
    R = float(np.sum(np.abs(c[~real])))
    cr = c[real][c[real] != 0]
    half = math.pi / 2

    def h(th):
        return (np.sum(np.abs((np.exp(-1j * th) * cr).real)) + R) / math.cos(th)

    kinks = np.unique(np.angle(cr) % math.pi - half)     # Re(e^{−jθ} c_i) = 0
    kinks = kinks[np.abs(kinks) < half]
    cand = [h(x) for x in kinks]
    edges = np.r_[-half, kinks, half]
    for lo, hi in zip(edges[:-1], edges[1:]):
        s = np.sign((np.exp(-1j * 0.5 * (lo + hi)) * cr).real)
        A, B = float(np.sum(s * cr.real)), float(np.sum(s * cr.imag))
        if R > abs(B) and lo < math.asin(-B / R) < hi:
            cand.append(A + math.sqrt(R * R - B * B))
        elif R == 0.0 and B == 0.0:              # h constant on a piece reaching ±π/2
            cand.append(A)
    return float(min(cand))


def _random_rank_one(rng, kind):
    n = int(rng.integers(2, 7))
    a = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    b = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    real = {"real": np.ones(n, bool), "complex": np.zeros(n, bool),
            "mixed": rng.random(n) < 0.5}[kind]
    return np.outer(a, b.conj()), a * b.conj(), real


def test_exact_solver_closed_forms_and_its_dual():
    rng = np.random.default_rng(RNG_SEED)
    c = rng.standard_normal(5) + 1j * rng.standard_normal(5)
    s = np.sum(np.abs(c))
    assert rank_one_mu(c, np.zeros(5, bool)) == pytest.approx(s, rel=1e-14)   # Σ|c_i|
    assert rank_one_mu(np.abs(c) * np.sign(c.real), np.ones(5, bool)) == pytest.approx(s)
    assert rank_one_mu(np.abs(c) * np.exp(1j * np.pi / 3), np.ones(5, bool)) == pytest.approx(
        0.0, abs=1e-12)                          # a common phase of 60°: no real δ cancels it
    # one real and one complex scalar, c = (1, j): t = 1 + √(1 − 0) … the disc of radius 1
    # around the segment [−1, 1] meets the real axis at 2
    assert rank_one_mu([1.0, 1j], [True, False]) == pytest.approx(2.0)
    # c = (j, 1) with the first real: the segment [−j, j] plus the unit disc reaches 1 on the
    # axis (its vertex ±j is one unit above it)
    assert rank_one_mu([1j, 1.0], [True, False]) == pytest.approx(1.0)
    # primal (an attained point) = dual (an upper bound at every θ) on random mixed cases
    for kind in ("real", "complex", "mixed") * 10:
        _, c, real = _random_rank_one(rng, kind)
        assert rank_one_mu(c, real) == pytest.approx(rank_one_mu_dual(c, real), rel=1e-12)


def test_rank_one_mu_is_where_det_vanishes():
    # μ = t* means a δ of size 1/t* makes I − MΔ singular and none smaller: check the real
    # 2-scalar case by brute force over the unit square's boundary (δ = (±1, s) or (s, ±1))
    rng = np.random.default_rng(RNG_SEED + 1)
    Z, c, real = _random_rank_one(rng, "real")
    Z, c, real = Z[:2, :2], c[:2], real[:2]
    t = rank_one_mu(c, real)
    s = np.linspace(-1.0, 1.0, 200001)
    pts = np.concatenate([x * c[0] + s * c[1] for x in (-1, 1)]
                         + [s * c[0] + x * c[1] for x in (-1, 1)])
    # the largest real t with t ∈ S: the boundary points closest to the positive real axis
    on_axis = pts[np.abs(pts.imag) < 1e-4 * np.abs(c).sum()]
    assert t == pytest.approx(max(on_axis.real.max(), 0.0), rel=1e-3, abs=1e-9)


# ------------------------------------------------------------------- the bound against it
@pytest.mark.slow
def test_whole_call_keeps_the_bound_tight_where_the_reduced_call_alone_is_not():
    # two real scalars, rank one: μ = 0.0542 (real δ can hardly cancel these phases); the
    # regularised, reduced call alone certifies 20× that, the whole call 1.06×
    a = np.array([-0.23 + 0.62j, -0.86 - 1.76j])
    b = np.array([-1.03 - 1.36j, 0.04 + 0.028j])
    Z, c = np.outer(a, b.conj()), a * b.conj()
    exact = rank_one_mu(c, [True, True])
    assert exact == pytest.approx(rank_one_mu_dual(c, [True, True]), rel=1e-12)
    reduced, _ = MU.mu_upper_bound(Z, [1, 1], [1, 1], whole=False)
    mu, info = MU.mu_upper_bound(Z, [1, 1], [1, 1])
    assert reduced > 10.0 * exact
    assert info["source"] == "whole" and not info["fallback"]
    assert exact * (1 - 1e-9) <= mu <= exact * (1 + TIGHT)
    # with a wall-clock limit the call runs in a child process: the same certificate in time,
    # the reduced call's when it is stopped (never an uncertified value)
    limited, info_l = MU.mu_upper_bound(Z, [1, 1], [1, 1], whole_timeout_s=60.0)
    assert limited == pytest.approx(mu, rel=1e-12) and not info_l["whole_timed_out"]
    stopped, info_s = MU.mu_upper_bound(Z, [1, 1], [1, 1], whole_timeout_s=0.0)
    assert info_s["whole_timed_out"] and info_s["source"] == "reduced"
    assert stopped == pytest.approx(reduced, rel=1e-12)


@pytest.mark.slow
def test_rank_one_bound_never_below_and_within_ten_percent_of_exact():
    rng = np.random.default_rng(RNG_SEED + 2)
    ratios = []
    for k in range(N_RANDOM):
        Z, c, real = _random_rank_one(rng, ("real", "complex", "mixed")[k % 3])
        exact = rank_one_mu(c, real)
        mu, info = MU.mu_upper_bound(Z, np.ones(c.size, int), np.where(real, 1, 2))
        assert not info["fallback"]
        assert exact > 0.0 and mu >= exact * (1 - 1e-9), (k, mu, exact)
        assert mu <= exact * (1 + TIGHT), (k, mu, exact)
        ratios.append(mu / exact)
    print(f"bound/exact over {N_RANDOM} cases: max {max(ratios):.4f}, mean {np.mean(ratios):.4f}")
    assert np.mean(ratios) < 1.02


# ------------------------------------------------------------------- published examples
def _packard_doyle():
    g, beta = 3.0 + math.sqrt(3.0), math.sqrt(3.0) - 1.0
    a, b = math.sqrt(2.0 / g), 1.0 / math.sqrt(g)
    c, d, f = b, -math.sqrt(beta / g), (1 + 1j) * math.sqrt(1.0 / (g * beta))
    psi1, psi2 = -math.pi / 2, math.pi
    U = np.array([[a, 0], [b, b], [c, 1j * c], [d, f]])
    V = np.array([[0, a], [b, -b], [c, -1j * c], [f * np.exp(1j * psi1), d * np.exp(1j * psi2)]])
    return U, V


@pytest.mark.slow
def test_packard_doyle_gap_example():
    U, V = _packard_doyle()
    assert np.allclose(U.conj().T @ U, np.eye(2)) and np.allclose(V.conj().T @ V, np.eye(2))
    Z = U @ V.conj().T                           # σ̄ = 1: D = I certifies 1, the optimum
    mu, info = MU.mu_upper_bound(Z, [1] * 4, [2] * 4)
    assert 1.0 - 1e-9 <= mu <= 1.0 + 1e-6       # the stated D-scaled bound
    assert not info["fallback"]
    # μ itself (complex scalars: max over unit phases Q of the spectral radius of QZ), by a
    # grid and a local search: ≈ 0.87 as stated; the bound's gap is the (D, G) bound's own
    th = np.linspace(0.0, 2 * np.pi, 17)[:-1]
    T = np.stack(np.meshgrid(th, th, th, indexing="ij"), -1).reshape(-1, 3)
    Q = np.exp(1j * np.c_[np.zeros(len(T)), T])

    def rho(q):
        return np.abs(np.linalg.eigvals(q[..., :, None] * Z)).max(-1)

    x0 = T[int(np.argmax(rho(Q)))]
    res = minimize(lambda x: -rho(np.exp(1j * np.r_[0.0, x])), x0, method="Nelder-Mead",
                   options={"xatol": 1e-10, "fatol": 1e-12})
    lower = -res.fun
    assert 0.864113 <= lower <= 0.88 and lower <= mu


def test_slicot_ab13md_documentation_example():
    rows = np.array([[-1 + 6j, 2 - 3j, 3 + 8j, 3 + 8j, -5 - 9j, -6 + 2j],
                     [4 + 2j, -2 + 5j, -6 - 7j, -4 + 11j, 8 - 7j, 12 - 1j],
                     [5 - 4j, -4 - 8j, 1 - 3j, -6 + 14j, 2 - 5j, 4 + 16j]])
    Z = np.vstack([rows, rows])
    mu, info = MU.mu_upper_bound(Z, [1, 1, 2, 1, 1], [1, 1, 2, 2, 2])
    assert mu == pytest.approx(41.74753408, rel=1e-8)
    assert not info["fallback"]
    # the regularised, reduced call alone certifies a larger value
    assert info["certified"] > mu
