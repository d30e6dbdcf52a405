"""A primal-dual interior-point method for the synthesis SDPs, solved by the normal equations.

Why (docs/SYNTHESIS.md §8): the synthesis SDPs have ~1 100 free variables (the coefficients of
X(ρ), Y(ρ)) and many small PSD cones (4–6 per grid point, sizes 19–38) whose constraint rows
are sparse (an LMI entry depends on a few dozen variables, a coupling entry on three).
Clarabel factorises the whole KKT system with a sparse LDLᵀ, in which every cone's dense
scaling block fills in against all the variables it touches: the cost per iteration grows with
d_k·m_k² per cone (d_k = svec size, m_k = variables touched) and dominated the synthesis time.
The Schur-complement (normal equations) form M = Σ_k A_kᵀ H_k A_k keeps A_k sparse: its cost per
cone is nnz(A_k)·d_k, and the dense Cholesky of M (~1 100²) is cheap. This is what the classical
SDP codes (SDPT3, SeDuMi, MOSEK) do.

The method: infeasible-start primal-dual path following with Nesterov–Todd scaling and
Mehrotra's predictor-corrector (the direction of CVXOPT's conelp / SDPT3's NT direction), on the
conic form cvxpy hands to Clarabel:

    minimise cᵀx  subject to  Ax + s = b,  s ∈ K;   dual: Aᵀz + c = 0,  z ∈ K,

K a product of non-negative orthants and PSD cones in Clarabel's svec convention (upper triangle,
column-major, off-diagonal entries scaled by √2). Zero cones and second-order cones are not
supported (the synthesis problems have none). Every answer is checked independently by the
caller (lpv_synthesis._check_lmis and the certificate), as Clarabel's are.
"""

from __future__ import annotations

import contextlib
import ctypes
import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

__all__ = ["IpmSolution", "solve_conic", "solve_conic_hsde"]

# cone blocks of A denser than this are multiplied as dense arrays (BLAS beats scipy's
# single-threaded sparse × dense product by far at these sizes)
_DENSE_FRACTION = 0.02

SOLVED, ALMOST_SOLVED, MAX_ITERATIONS, NUMERICAL_ERROR = (
    "Solved", "AlmostSolved", "MaxIterations", "NumericalError")


@dataclass
class IpmSolution:
    """Clarabel-like answer (the attributes cvxpy's Clarabel interface reads in ``invert``)."""

    status: str
    x: np.ndarray
    s: np.ndarray
    z: np.ndarray
    obj_val: float
    iterations: int
    solve_time: float
    pres: float = float("nan")
    dres: float = float("nan")
    gap: float = float("nan")


@contextlib.contextmanager
def single_threaded_blas():
    """Run the block with every loaded OpenBLAS (numpy's and scipy's) on one thread.

    The matrices here are small (≤ ~1 200): on the shared two-core machine OpenBLAS' threads
    made a 1 142² Cholesky take 0.9–1.3 s at load 5 instead of 0.016 s on one thread.
    """
    restore = []
    try:
        with open("/proc/self/maps") as maps:
            paths = sorted({line.split()[-1] for line in maps if "openblas" in line.lower()})
    except OSError:
        paths = []
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for suffix in ("64_", ""):
            for prefix in ("scipy_openblas", "openblas"):
                get = getattr(lib, f"{prefix}_get_num_threads{suffix}", None)
                set_ = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
                if get is not None and set_ is not None:
                    restore.append((set_, int(get())))
                    set_(1)
                    break
            else:
                continue
            break
    try:
        yield
    finally:
        for set_, n in restore:
            set_(n)


class _Cone:
    """One PSD cone of order n (a non-negative entry is a cone of order 1)."""

    _index_cache: dict = {}

    def __init__(self, n, start, A):
        self.n, self.d = n, n * (n + 1) // 2
        self.rows = slice(start, start + self.d)
        if n not in self._index_cache:
            pairs = [(i, j) for j in range(n) for i in range(j + 1)]
            rows = np.array([p[0] for p in pairs], dtype=int)
            cols = np.array([p[1] for p in pairs], dtype=int)
            off = rows != cols
            scale = np.where(off, np.sqrt(2.0), 1.0)
            coef = np.outer(scale, np.where(off, 1.0 / np.sqrt(2.0), 0.5))
            # flat indices into Q.ravel() for skron (np.take is ≈ 2× faster than 2-D fancy
            # indexing with np.ix_ at n = 38)
            flat = [(a[:, None] * n + b[None, :]).astype(np.int32)
                    for a, b in ((rows, rows), (cols, cols), (rows, cols), (cols, rows))]
            self._index_cache[n] = (rows, cols, scale, coef, *flat)
        (self.I, self.J, self.scale, self.coef, self.ii, self.jj, self.ij,
         self.ji) = self._index_cache[n]
        Ak = A[self.rows, :].tocsc()
        self.cols = np.flatnonzero(np.diff(Ak.indptr))
        Ak = Ak[:, self.cols]
        self.dense = Ak.nnz > _DENSE_FRACTION * Ak.shape[0] * Ak.shape[1]
        self.Ak = Ak.toarray() if self.dense else Ak.tocsr()
        self.AkT = self.Ak.T if self.dense else Ak.T.tocsr()
        # dense cones: the columns of A_k as symmetric matrices F_j (m_k × n × n), so that
        # A_kᵀ H A_k = ÃᵀÃ with Ã_j = svec(R⁻¹ F_j R⁻ᵀ) (H = svec form of M ↦ QMQ, Q = R⁻ᵀR⁻¹)
        self.F = self.mat(self.Ak.T) if self.dense else None
        self.key = self.cols.tobytes()
        # where A_kᵀ H_k A_k goes in M: a slice when the columns are contiguous (fancy-index
        # addition of a 1 141² block cost 20 ms against 5 ms)
        contiguous = self.cols.size and self.cols[-1] - self.cols[0] + 1 == self.cols.size
        self.block = ((slice(self.cols[0], self.cols[-1] + 1),) * 2 if contiguous
                      else np.ix_(self.cols, self.cols))

    def mat(self, v):
        """Symmetric matrix of svec v (or a stack of them: v of shape (..., d))."""
        M = np.empty(v.shape[:-1] + (self.n, self.n))
        w = v / self.scale
        M[..., self.I, self.J] = w
        M[..., self.J, self.I] = w
        return M

    def vec(self, M):
        return 0.5 * (M[..., self.I, self.J] + M[..., self.J, self.I]) * self.scale

    def skron(self, Q):
        """svec form of the operator M ↦ QMQ (Q symmetric)."""
        q = Q.ravel()
        return self.coef * (q.take(self.ii) * q.take(self.jj) + q.take(self.ij) * q.take(self.ji))


def _max_step(lam, dM):
    """Largest α ≤ 1/0 such that diag(λ) + α dM ⪰ 0 (inf if no limit)."""
    r = 1.0 / np.sqrt(lam)
    e = np.linalg.eigvalsh((r[:, None] * dM) * r[None, :])[0]
    return np.inf if e >= 0.0 else -1.0 / e


def solve_conic(A, b, c, psd_dims=(), n_nonneg=0, n_zero=0, max_iter=100, tol_feas=1e-7,
                tol_gap_abs=1e-7, tol_gap_rel=1e-4, reduced_tol=1e-3, step_fraction=0.99,
                refine_steps=3, stall_window=6, verbose=False, centring_floor=0.0):
    """Solve min cᵀx s.t. Ax + s = b, s ∈ R₊^{n_nonneg} × PSD cones (in that row order).

    Returns an :class:`IpmSolution`; status "Solved" when the feasibility and gap tolerances
    are met, "AlmostSolved" when the solver stalls (the best of max(residuals, gap) has not
    halved in ``stall_window`` iterations) or stops with the residuals and gap below
    ``reduced_tol`` (relative), otherwise "MaxIterations" / "NumericalError".

    The default gap tolerance is relative 1e-4: on the synthesis problems the normal equations
    lose accuracy near the optimum (relative gaps stall at 2e-5–3e-4 on the 3- and 9-point
    problems), and the primal iterates are strictly feasible once the primal residual has
    vanished (≈ 1e-14 after ~10 iterations), so a relative gap of 1e-4 bounds the γ error by
    ≈ 0.01 %, far inside the 0.5 % tolerance of the synthesis; every answer is checked
    independently by the caller anyway.
    """
    with single_threaded_blas():
        return _solve_conic(A, b, c, psd_dims, n_nonneg, n_zero, max_iter, tol_feas, tol_gap_abs,
                            tol_gap_rel, reduced_tol, step_fraction, refine_steps, stall_window,
                            verbose, centring_floor)


def _problem(A, b, c, psd_dims, n_nonneg, n_zero):
    """The problem data as arrays and its cones (nonnegative first, then PSD), checked against
    the rows of ``A``: (A as CSR, b, c, rows, columns, cones)."""
    if n_zero:
        raise ValueError("sdp_ipm: zero cones are not supported")
    A = sp.csr_matrix(A)
    b = np.asarray(b, dtype=float)
    c = np.asarray(c, dtype=float)
    m, nv = A.shape
    cones, row = [], 0
    for _ in range(n_nonneg):
        cones.append(_Cone(1, row, A))
        row += 1
    for n in psd_dims:
        cones.append(_Cone(int(n), row, A))
        row += cones[-1].d
    if row != m:
        raise ValueError(f"sdp_ipm: cone sizes {row} do not match the {m} rows of A")
    return A, b, c, m, nv, cones


def _solve_conic(A, b, c, psd_dims, n_nonneg, n_zero, max_iter, tol_feas, tol_gap_abs,
                 tol_gap_rel, reduced_tol, step_fraction, refine_steps, stall_window, verbose,
                 centring_floor=0.0):
    start_time = time.perf_counter()
    A, b, c, m, nv, cones = _problem(A, b, c, psd_dims, n_nonneg, n_zero)
    nu = sum(k.n for k in cones)
    AT = A.T.tocsr()
    b_norm, c_norm = max(1.0, np.linalg.norm(b)), max(1.0, np.linalg.norm(c))

    # initial point: x = 0, S = Z = ξI
    xi_p = max(1.0, np.sqrt(np.max(np.abs(b))) if b.size else 1.0)
    xi_d = max(1.0, np.sqrt(np.max(np.abs(c))) if c.size else 1.0)
    xi = 10.0 * max(xi_p, xi_d)
    x = np.zeros(nv)
    S = [xi * np.eye(k.n) for k in cones]
    Z = [xi * np.eye(k.n) for k in cones]

    def vec_all(mats):
        return np.concatenate([k.vec(M) for k, M in zip(cones, mats)])

    status, it, last_step = MAX_ITERATIONS, 0, 1.0
    best = None
    history = []
    pres = dres = gap = np.inf
    for it in range(max_iter + 1):
        s, z = vec_all(S), vec_all(Z)
        r_p = A @ x + s - b
        r_d = AT @ z + c
        pcost, dcost = float(c @ x), float(-b @ z)
        gap = float(s @ z)
        mu = gap / nu
        pres = np.linalg.norm(r_p) / b_norm
        dres = np.linalg.norm(r_d) / c_norm
        rel_gap = gap / max(1e-12, min(abs(pcost), abs(dcost)))
        if verbose:
            print(f"{it:3d} pcost {pcost:+.6e} dcost {dcost:+.6e} gap {gap:.2e} pres {pres:.2e} "
                  f"dres {dres:.2e} mu {mu:.2e} t {time.perf_counter() - start_time:.2f}")
        score = max(pres, dres, min(gap, rel_gap))
        if best is None or score < best[0]:
            best = (score, x.copy(), s.copy(), z.copy(), pres, dres, gap, rel_gap)
        if pres < tol_feas and dres < tol_feas and (gap < tol_gap_abs or rel_gap < tol_gap_rel):
            status = SOLVED
            break
        if it == max_iter:
            break
        history.append(score)
        if len(history) > stall_window and score > 0.5 * history[-1 - stall_window]:
            break                                     # no progress: stop with the best iterate
        try:
            # Nesterov–Todd scaling per cone: R with Rᵀ Z R = R⁻¹ S R⁻ᵀ = Λ
            scal, M = _nt_scaling(cones, S, Z, nv)
            try:
                factor = _cholesky(M)
            except np.linalg.LinAlgError:
                if verbose:
                    ev = np.linalg.eigvalsh(M)
                    print("normal equations not positive definite:", ev[:3], ev[-1])
                status = NUMERICAL_ERROR
                break

            def direction(D_list):
                T = [R @ (2.0 * Dk / (lam[:, None] + lam[None, :])) @ R.T
                     for (R, _, lam, *_), Dk in zip(scal, D_list)]
                w = r_p + vec_all(T)
                rhs = -r_d.copy()
                Hw = []
                for k, sc in zip(cones, scal):
                    hw = _apply_H(k, sc, w[k.rows])
                    Hw.append(hw)
                    rhs[k.cols] -= k.AkT @ hw
                dx = sla.cho_solve(factor, rhs, check_finite=False)
                # iterative refinement of M dx = rhs with M applied through A and H
                Adx = A @ dx
                rhs_norm = max(1.0, np.linalg.norm(rhs))
                for _ in range(refine_steps + 1):
                    Mdx = np.zeros(nv)
                    dz_parts = []
                    for k, sc, hw in zip(cones, scal, Hw):
                        hA = _apply_H(k, sc, Adx[k.rows])
                        Mdx[k.cols] += k.AkT @ hA
                        dz_parts.append(hA + hw)
                    res = rhs - Mdx
                    if np.linalg.norm(res) <= 1e-14 * rhs_norm:
                        break
                    ddx = sla.cho_solve(factor, res, check_finite=False)
                    dx = dx + ddx
                    Adx = Adx + A @ ddx
                else:
                    Addx = A @ ddx
                    dz_parts = [dzp + _apply_H(k, sc, Addx[k.rows])
                                for k, sc, dzp in zip(cones, scal, dz_parts)]
                ds = -r_p - Adx
                dS = [k.mat(ds[k.rows]) for k in cones]
                dZ = [k.mat(dzp) for k, dzp in zip(cones, dz_parts)]
                return dx, dS, dZ

            def steps(dS, dZ):
                a_p = a_d = np.inf
                hats = []
                for (R, Rinv, lam, *_), dSk, dZk in zip(scal, dS, dZ):
                    dS_hat = Rinv @ dSk @ Rinv.T
                    dZ_hat = R.T @ dZk @ R
                    hats.append((dS_hat, dZ_hat))
                    a_p = min(a_p, _max_step(lam, dS_hat))
                    a_d = min(a_d, _max_step(lam, dZ_hat))
                return a_p, a_d, hats

            # predictor (affine scaling)
            D_aff = [np.diag(-lam ** 2) for (_, _, lam, *_) in scal]
            dx_a, dS_a, dZ_a = direction(D_aff)
            a_p, a_d, hats = steps(dS_a, dZ_a)
            a_p, a_d = min(1.0, a_p), min(1.0, a_d)
            mu_aff = sum(float(np.sum((Sk + a_p * dSk) * (Zk + a_d * dZk)))
                         for Sk, Zk, dSk, dZk in zip(S, Z, dS_a, dZ_a)) / nu
            sigma = float(np.clip((mu_aff / mu) ** 3, 0.0, 1.0))
            if last_step < 0.2:            # short steps: more centring (``centring_floor``)
                sigma = max(sigma, centring_floor)
            # corrector (centring + second-order term)
            D = []
            for (_, _, lam, *_), (dSh, dZh) in zip(scal, hats):
                prod = dSh @ dZh
                D.append(np.diag(sigma * mu - lam ** 2) - 0.5 * (prod + prod.T))
            dx, dS, dZ = direction(D)
            a_p, a_d, _ = steps(dS, dZ)
            a_p = min(1.0, step_fraction * a_p)
            a_d = min(1.0, step_fraction * a_d)
            last_step = min(a_p, a_d)
            if not (a_p > 1e-10 or a_d > 1e-10):
                if verbose:
                    print("step lengths", a_p, a_d)
                status = NUMERICAL_ERROR
                break
            x = x + a_p * dx
            S = [Sk + a_p * dSk for Sk, dSk in zip(S, dS)]
            Z = [Zk + a_d * dZk for Zk, dZk in zip(Z, dZ)]
        except np.linalg.LinAlgError as error:
            if verbose:
                print("linear algebra error:", error)
            status = NUMERICAL_ERROR
            break
    if status != SOLVED:
        # the best iterate, if it meets the reduced tolerances
        _, x, s, z, pres, dres, gap, rel_gap = best
        if pres < reduced_tol and dres < reduced_tol and (gap < reduced_tol
                                                          or rel_gap < reduced_tol):
            status = ALMOST_SOLVED
    else:
        s, z = vec_all(S), vec_all(Z)
    return IpmSolution(status, x, s, z, float(c @ x), it, time.perf_counter() - start_time,
                       float(pres), float(dres), float(gap))


PRIMAL_INFEASIBLE, DUAL_INFEASIBLE = "PrimalInfeasible", "DualInfeasible"


def _nt_scaling(cones, S, Z, nv):
    """Nesterov–Todd scaling of every cone and the normal-equations matrix M = Σ A_kᵀ H_k A_k.

    Per cone: R with Rᵀ Z R = R⁻¹ S R⁻ᵀ = diag(λ), Q = (RRᵀ)⁻¹ and H = svec form of M ↦ QMQ
    (H = W⁻¹ ⊗ W⁻¹ in the usual notation), so that the linearised complementarity reads
    ds + H⁻¹ dz = (a term of the right-hand side).
    """
    scal = []
    M = np.zeros((nv, nv))
    groups = {}                   # dense cones by column set: (block, [Ã_k]) → M[block] += ÃÃᵀ
    for k, Sk, Zk in zip(cones, S, Z):
        Ls = np.linalg.cholesky(Sk)
        Lz = np.linalg.cholesky(Zk)
        U, lam, Vt = np.linalg.svd(Lz.T @ Ls)
        R = Ls @ (Vt.T / np.sqrt(lam))
        Rinv = (U.T / np.sqrt(lam)[:, None]) @ Lz.T       # R⁻¹ = Λ^{-1/2} Uᵀ L_zᵀ
        Q = Rinv.T @ Rinv
        if k.dense:
            H = None
            groups.setdefault(k.key, (k.block, []))[1].append(k.vec(Rinv @ k.F @ Rinv.T))
        else:
            H = k.skron(Q)
            M[k.block] += (k.AkT @ (k.AkT @ H).T).T
        scal.append((R, Rinv, lam, H, Q))
    for block, parts in groups.values():
        At = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
        # ÃÃᵀ by a symmetric rank-k update (half the flops of a product); Ãᵀ is Fortran-ordered
        upper = sla.blas.dsyrk(1.0, At.T, trans=1)
        M[block] += upper + np.triu(upper, 1).T
    return scal, 0.5 * (M + M.T)


def _apply_H(k, sc, v):
    """H_k v for cone k with its scaling sc = (R, R⁻¹, λ, H or None, Q): svec(Q mat(v) Q)."""
    H, Q = sc[3], sc[4]
    return H @ v if H is not None else k.vec(Q @ k.mat(v) @ Q)


def _cholesky(M):
    """Cholesky factor of M, with a tiny diagonal shift if it is numerically semidefinite."""
    diag_max = max(1.0, float(np.max(np.diag(M))))
    for delta in (0.0, 1e-14, 1e-12, 1e-10):
        try:
            return sla.cho_factor(M + delta * diag_max * np.eye(M.shape[0]), lower=True,
                                  check_finite=False)
        except np.linalg.LinAlgError:
            continue
    raise np.linalg.LinAlgError("normal equations not positive definite")


def _least_squares_start(A, AT, b, c, cones):
    """Starting point of CVXOPT's conelp and Clarabel: the least-norm s with Ax + s = b and the
    least-norm z with Aᵀz + c = 0, each shifted along the identity into the interior of K if
    it is not already inside (min eigenvalue raised to 1). Much better than x = 0, S = Z = I on
    badly scaled problems (the stage-2 bound X ≤ cI has c ≈ 3 400 next to entries ≈ 1).
    """
    AtA = (AT @ A).toarray()
    factor = _cholesky(0.5 * (AtA + AtA.T))
    x = sla.cho_solve(factor, AT @ b, check_finite=False)
    s = b - A @ x
    z = -(A @ sla.cho_solve(factor, c, check_finite=False))

    def interior(v):
        mats = [k.mat(v[k.rows]) for k in cones]
        low = min(np.linalg.eigvalsh(Mk)[0] for Mk in mats)
        scale = max(1.0, float(np.linalg.norm(v)))
        if low <= 1e-8 * scale:
            mats = [Mk + (1.0 - low) * np.eye(Mk.shape[0]) for Mk in mats]
        return mats

    return x, interior(s), interior(z)


def solve_conic_hsde(A, b, c, psd_dims=(), n_nonneg=0, n_zero=0, max_iter=100, tol_feas=1e-7,
                     tol_gap_abs=1e-7, tol_gap_rel=1e-4, tol_infeas=1e-8, reduced_tol=1e-3,
                     step_fraction=0.99, refine_steps=3, stall_window=6, verbose=False,
                     tol_dual=None):
    """:func:`solve_conic` on the homogeneous self-dual embedding (no feasible start needed).

    The embedding (Ye, Todd & Mizuno 1994; the form of CVXOPT's conelp and Clarabel):

        A x + s = b τ,   Aᵀ z + c τ = 0,   cᵀx + bᵀz + κ = 0,   s, z ∈ K,  τ, κ ≥ 0,

    started at x = 0, S = Z = I, τ = κ = 1 (always interior). At a solution with τ > 0,
    (x, s, z)/τ solves the problem; τ → 0 with κ > 0 gives a certificate of primal (bᵀz < 0)
    or dual (cᵀx < 0) infeasibility. The Newton system is reduced to the same normal
    equations M = Σ A_kᵀ H_k A_k as in :func:`solve_conic`, solved for two right-hand sides
    (the residuals and the (b, c) column of the embedding); dτ then follows from the scalar
    gap equation. Why an embedding: the infeasible-start iteration of :func:`solve_conic`
    stalled on the synthesis' stage 2 (docs/SYNTHESIS.md §8), whose feasible set is thin
    (the stage-1 answer violates its robustness-margin LMIs).

    Statuses as :func:`solve_conic`, plus "PrimalInfeasible" / "DualInfeasible" (cvxpy maps
    them to infeasible / unbounded). ``tol_dual`` (default ``tol_feas``) is the tolerance of
    the relative dual residual: a caller who needs a primal feasible point near the optimum
    (not the dual certificate of its optimality) may relax it.
    """
    with single_threaded_blas():
        return _solve_hsde(A, b, c, psd_dims, n_nonneg, n_zero, max_iter, tol_feas,
                           tol_gap_abs, tol_gap_rel, tol_infeas, reduced_tol, step_fraction,
                           refine_steps, stall_window, verbose,
                           tol_feas if tol_dual is None else tol_dual)


def _solve_hsde(A, b, c, psd_dims, n_nonneg, n_zero, max_iter, tol_feas, tol_gap_abs,
                tol_gap_rel, tol_infeas, reduced_tol, step_fraction, refine_steps,
                stall_window, verbose, tol_dual):
    start_time = time.perf_counter()
    A, b, c, m, nv, cones = _problem(A, b, c, psd_dims, n_nonneg, n_zero)
    nu = sum(k.n for k in cones) + 1                      # + the (τ, κ) pair
    AT = A.T.tocsr()
    b_norm, c_norm = max(1.0, np.linalg.norm(b)), max(1.0, np.linalg.norm(c))

    def vec_all(mats):
        return np.concatenate([k.vec(M) for k, M in zip(cones, mats)])

    x, S, Z = _least_squares_start(A, AT, b, c, cones)
    tau = kappa = 1.0
    status, it, best, history, short_steps = MAX_ITERATIONS, 0, None, [], 0
    pres = dres = gap = np.inf
    for it in range(max_iter + 1):
        s, z = vec_all(S), vec_all(Z)
        r_p = A @ x + s - b * tau
        r_d = AT @ z + c * tau
        r_g = float(c @ x + b @ z) + kappa
        mu = (float(s @ z) + tau * kappa) / nu
        pcost, dcost = float(c @ x) / tau, float(-b @ z) / tau
        gap = float(s @ z) / tau ** 2
        pres = np.linalg.norm(r_p) / tau / b_norm
        dres = np.linalg.norm(r_d) / tau / c_norm
        rel_gap = gap / max(1e-12, min(abs(pcost), abs(dcost)))
        if verbose:
            print(f"{it:3d} pcost {pcost:+.6e} dcost {dcost:+.6e} gap {gap:.2e} pres {pres:.2e} "
                  f"dres {dres:.2e} tau {tau:.2e} kappa {kappa:.2e} "
                  f"t {time.perf_counter() - start_time:.2f}")
        score = max(pres, dres, min(gap, rel_gap))
        if best is None or score < best[0]:
            best = (score, x / tau, s / tau, z / tau, pres, dres, gap, rel_gap)
        if pres < tol_feas and dres < tol_dual and (gap < tol_gap_abs or rel_gap < tol_gap_rel):
            status = SOLVED
            break
        # infeasibility certificates (normalised by the size of the ray)
        btz, ctx = float(b @ z), float(c @ x)
        if btz < 0.0 and np.linalg.norm(AT @ z) / c_norm <= -tol_infeas * btz / b_norm * 1e3 \
                and tau < 1e-6 * kappa:
            status = PRIMAL_INFEASIBLE
            break
        if ctx < 0.0 and np.linalg.norm(A @ x + s) / b_norm <= -tol_infeas * ctx / c_norm * 1e3 \
                and tau < 1e-6 * kappa:
            status = DUAL_INFEASIBLE
            break
        if it == max_iter:
            break
        history.append(score)
        if len(history) > stall_window and score > 0.5 * history[-1 - stall_window]:
            break
        try:
            scal, M = _nt_scaling(cones, S, Z, nv)
            factor = _cholesky(M)

            def apply_H(v):
                return [_apply_H(k, sc, v[k.rows]) for k, sc in zip(cones, scal)]

            def AtH(v):
                out = np.zeros(nv)
                for k, hv in zip(cones, apply_H(v)):
                    out[k.cols] += k.AkT @ hv
                return out

            def solve_M(rhs):
                dx = sla.cho_solve(factor, rhs, check_finite=False)
                rhs_norm = max(1.0, np.linalg.norm(rhs))
                for _ in range(refine_steps):
                    res = rhs - AtH(A @ dx)
                    if np.linalg.norm(res) <= 1e-14 * rhs_norm:
                        break
                    dx = dx + sla.cho_solve(factor, res, check_finite=False)
                return dx

            # the embedding's (b, c) column: M dx2 = AᵀHb − c, dz2 = H(A dx2 − b)
            dx2 = solve_M(AtH(b) - c)
            u2 = A @ dx2 - b
            dz2 = np.concatenate(apply_H(u2))
            denom2 = float(c @ dx2 + b @ dz2)                 # = −‖H^½(A dx2 − b)‖² < 0

            def direction(D_list, d_tk, eta):
                """Newton direction: complementarity right-hand sides D (scaled cones) and
                d_tk (τ dκ + κ dτ = d_tk), residuals scaled by η."""
                T = [R @ (2.0 * Dk / (lam[:, None] + lam[None, :])) @ R.T
                     for (R, _, lam, *_), Dk in zip(scal, D_list)]
                w = eta * r_p + vec_all(T)
                dx1 = solve_M(-eta * r_d - AtH(w))
                u1 = A @ dx1 + w
                dz1 = np.concatenate(apply_H(u1))
                kt = d_tk / tau
                d_tau = ((-eta * r_g - kt - float(c @ dx1 + b @ dz1))
                         / (denom2 - kappa / tau))
                dx = dx1 + d_tau * dx2
                dz = dz1 + d_tau * dz2
                ds = -eta * r_p - A @ dx + b * d_tau
                d_kappa = kt - kappa / tau * d_tau
                dS = [k.mat(ds[k.rows]) for k in cones]
                dZ = [k.mat(dz[k.rows]) for k in cones]
                return dx, dS, dZ, d_tau, d_kappa

            def step(dS, dZ, d_tau, d_kappa):
                alpha = np.inf
                hats = []
                for (R, Rinv, lam, *_), dSk, dZk in zip(scal, dS, dZ):
                    dS_hat = Rinv @ dSk @ Rinv.T
                    dZ_hat = R.T @ dZk @ R
                    hats.append((dS_hat, dZ_hat))
                    alpha = min(alpha, _max_step(lam, dS_hat), _max_step(lam, dZ_hat))
                if d_tau < 0.0:
                    alpha = min(alpha, -tau / d_tau)
                if d_kappa < 0.0:
                    alpha = min(alpha, -kappa / d_kappa)
                return alpha, hats

            D_aff = [np.diag(-lam ** 2) for (_, _, lam, *_) in scal]
            dx_a, dS_a, dZ_a, dt_a, dk_a = direction(D_aff, -tau * kappa, 1.0)
            alpha, hats = step(dS_a, dZ_a, dt_a, dk_a)
            alpha = min(1.0, alpha)
            sigma = (1.0 - alpha) ** 3
            D = []
            for (_, _, lam, *_), (dSh, dZh) in zip(scal, hats):
                prod = dSh @ dZh
                D.append(np.diag(sigma * mu - lam ** 2) - 0.5 * (prod + prod.T))
            dx, dS, dZ, d_tau, d_kappa = direction(
                D, sigma * mu - tau * kappa - dt_a * dk_a, 1.0 - sigma)
            alpha, _ = step(dS, dZ, d_tau, d_kappa)
            alpha = min(1.0, step_fraction * alpha)
            if not alpha > 1e-10:
                status = NUMERICAL_ERROR
                break
            short_steps = short_steps + 1 if alpha < 1e-3 else 0
            if short_steps == 3:          # the normal equations' accuracy is exhausted
                break
            x = x + alpha * dx
            S = [Sk + alpha * dSk for Sk, dSk in zip(S, dS)]
            Z = [Zk + alpha * dZk for Zk, dZk in zip(Z, dZ)]
            tau += alpha * d_tau
            kappa += alpha * d_kappa
        except np.linalg.LinAlgError as error:
            if verbose:
                print("linear algebra error:", error)
            status = NUMERICAL_ERROR
            break
    if status == SOLVED:
        x, s, z = x / tau, vec_all(S) / tau, vec_all(Z) / tau
    elif status in (PRIMAL_INFEASIBLE, DUAL_INFEASIBLE):
        s, z = vec_all(S), vec_all(Z)
        scale = -float(b @ z) if status == PRIMAL_INFEASIBLE else -float(c @ x)
        x, s, z = x / scale, s / scale, z / scale
    else:
        _, x, s, z, pres, dres, gap, rel_gap = best
        if pres < reduced_tol and dres < reduced_tol and (gap < reduced_tol
                                                          or rel_gap < reduced_tol):
            status = ALMOST_SOLVED
    return IpmSolution(status, x, s, z, float(c @ x), it, time.perf_counter() - start_time,
                       float(pres), float(dres), float(gap))
