"""Grid-based, rate-bounded LPV H∞ (induced L2) output-feedback synthesis.

The mathematics: docs/LPV_SYNTHESIS.md §2–§3.

For the normalised plant (plant_scaling.py) find X(ρ), Y(ρ) = Σ_k φ_k(θ) X_k, Y_k with the basis
φ = [1, θ, θ²] (θ the normalised scheduling variable) and g = 1/γ such that at every grid point
ρ_i and every rate vertex ν the LMIs of docs/LPV_SYNTHESIS.md §2 hold (Wu, Yang, Packard & Becker
1996; the elimination form of Gahinet & Apkarian 1994; Apkarian & Adams 1998):

    LMI-X:  [ÂX + XÂᵀ − ∂X[ν] − B2B2ᵀ,  XC11ᵀ,  gB̂ ;  C11X, −I, gD_r ;  gB̂ᵀ, gD_rᵀ, −I] < 0
    LMI-Y:  [YÃ + ÃᵀY + ∂Y[ν] − C2ᵀC2,  YB11,  gC̃ᵀ ;  B11ᵀY, −I, gD_cᵀ ;  gC̃, gD_c, −I] < 0
    coupling: [X, gI; gI, Y] > 0

Two stages (§3): stage 1 maximises g (minimum γ) with a tiny trace regulariser; stage 2 fixes
g = 1/(backoff·γ_1) and maximises the coupling margin t with X, Y bounded, which gives a
well-conditioned controller. Every solver answer is checked independently (eigenvalues of every
LMI, then the closed-loop certificate of certificate.py) before it is accepted; a fallback solver
is tried when the first one fails or its answer does not pass.

Two additions to the recipe of §3, both found necessary on test plants:

- the strictness margin ε is relative (ε·V on the Lyapunov block, V = X or Y, plus ε times the
  scale of the constant terms), because the solver's absolute error grows with ‖V‖ and an
  absolute ε let slightly infeasible answers through or rejected good ones;
- stage 2 by default imposes the LMIs with a robustness margin τ (control and measurement
  authority, performance channels, decay rate): the plain stage 2 leaves every LMI active at
  the grid points, and the certificate then failed between grid points even for a smooth
  plant, for the exact as well as for the interpolated controller. (LMIs at the segment
  midpoints interpolated from the grid LMIs were tried too: they broke the solver on a
  19-state plant whose bending frequencies move by more than their bandwidth between points.)
"""

from __future__ import annotations

import itertools
import time
import warnings
from dataclasses import dataclass, field, replace

import cvxpy as cp
import numpy as np

from vega_lpv.certificate import certificate_check
from vega_lpv.gridded_plant import GriddedPlant, PlantDataError, PlantPoint
from vega_lpv.plant_scaling import PlantScaling, plant_scaling
from vega_lpv.reconstruction import controller_at
from vega_lpv.sdp_ipm import solve_conic, solve_conic_hsde

__all__ = ["SynthesisError", "LpvSynthesisResult", "synthesize"]

_ACCEPTED_STATUSES = (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)
# The in-house interior-point method (sdp_ipm.py, normal equations; docs/SYNTHESIS.md §8),
# selected with solver="IPM" (pipeline.SOLVER_PATHS["ipm"]), Clarabel (sparse LDLᵀ of the whole
# KKT system) as its fallback. Not a cvxpy solver name: the problem is canonicalised for
# Clarabel (same cone convention) and solved here.
IPM = "IPM"
_SOLVER_OPTIONS = {
    # faer: multithreaded supernodal LDLᵀ (qdldl is ~20× slower on the 19-state problem);
    # chordal decomposition only splits the identity blocks and costs accuracy; the tolerances
    # sit below the relative strictness margin ε. Equilibration: see _solve.
    "CLARABEL": {"max_iter": 300, "direct_solve_method": "faer",
                 "chordal_decomposition_enable": False,
                 "tol_feas": 1e-7, "tol_gap_abs": 1e-7, "tol_gap_rel": 1e-6},
    # first-order fallback: its answers rarely pass the eigenvalue checks on stiff plants, so
    # its time is capped (it spent the whole cap on the 19-state VEGA problem)
    "SCS": {"eps_abs": 1e-7, "eps_rel": 1e-7, "max_iters": 100_000, "time_limit_secs": 180.0},
}


# Clarabel's static KKT regularisation for further attempts after a solver error (default
# 1e-8): with the default, multi-point problems of the 19-state VEGA plant stopped at
# iteration 1 with a numerical error (KKT factorisation) — for some pairs of grid points and
# for all nine; 1e-6 solves them. It is not the default because it costs accuracy: the
# single-point LMI then lands 1.0–1.6 % above sb10ad at t = 70–90 s instead of within 1 %.
# A failed attempt stops within a few iterations, so the ladder is cheap.
_CLARABEL_RETRY_REGULARISATIONS = (1e-6, 1e-5, 1e-4)


class SynthesisError(ValueError):
    """The LMIs could not be solved to an answer that passes the independent checks."""


@dataclass(frozen=True)
class LpvSynthesisResult:
    """Outcome of :func:`synthesize`.

    Attributes
    ----------
    gamma_min : float
        Stage-1 optimum γ_1 = 1/g_1 (a certified upper bound of the best achievable level).
    gamma : float
        Performance level of the returned controller (stage 2: backoff·γ_1).
    X_k, Y_k : tuple of np.ndarray
        Coefficients of X(θ) = Σ_k θ^k X_k and Y(θ) in the balanced state coordinates, g-form
        (X_std = γX). One coefficient when the variable is constant.
    rate_vertices : tuple of float
        Values of ρ̇ at which the LMIs were imposed (empty for the quadratic variant).
    scaling : PlantScaling
        State, (w, e) and θ scalings of §1.
    points : tuple of NormalisedPoint
        The normalised plant at the grid values.
    rho : np.ndarray
        Grid values.
    sizes : tuple of int
        (n_w, n_u, n_e, n_y).
    t_margin : float
        Stage-2 coupling margin t ([X − tI, gI; gI, Y] ≥ 0); nan without stage 2.
    times_s : dict
        Per stage: wall time (problem construction, solve and checks), solver-reported time
        ("…_solver") and iteration count ("…_iterations").
    statuses : dict
        Solver status of the accepted answer of each stage.
    solvers : dict
        Solver that produced the accepted answer of each stage.
    lmi_max_eig : dict
        Largest eigenvalue over all LMIs of each stage (coupling entered as −[X, gI; gI, Y]);
        negative = satisfied.
    certificate_max_eig : float
        Largest certificate eigenvalue over the grid points and rate vertices (negative).
    robustness : float
        Stage-2 robustness margin τ actually used (0: plain stage 2 of §3, or no stage 2).
    rate_A : tuple of np.ndarray
        The plant's rate term N at the grid values in the balanced coordinates (T⁻¹ N T), or
        empty: the plant at (ρ_i, ρ̇) is A + ρ̇ N (GriddedPlant.N).
    """

    gamma_min: float
    gamma: float
    X_k: tuple
    Y_k: tuple
    rate_vertices: tuple
    scaling: PlantScaling
    points: tuple
    rho: np.ndarray
    sizes: tuple
    t_margin: float = float("nan")
    times_s: dict = field(default_factory=dict)
    statuses: dict = field(default_factory=dict)
    solvers: dict = field(default_factory=dict)
    lmi_max_eig: dict = field(default_factory=dict)
    certificate_max_eig: float = float("nan")
    robustness: float = 0.0
    rate_A: tuple = ()

    def X(self, rho):
        """X(ρ) = Σ_k θ^k X_k."""
        return _values_at(self.X_k, self.scaling.theta(rho), self.scaling.rho_half)[0]

    def Y(self, rho):
        """Y(ρ) = Σ_k θ^k Y_k."""
        return _values_at(self.Y_k, self.scaling.theta(rho), self.scaling.rho_half)[0]

    def dX_drho(self, rho):
        """∂X/∂ρ = (1/ρ_half) Σ_k k θ^(k−1) X_k (zero for a constant X)."""
        derivative = _values_at(self.X_k, self.scaling.theta(rho), self.scaling.rho_half)[1]
        return np.zeros_like(self.X_k[0]) if derivative is None else derivative

    def dY_drho(self, rho):
        """∂Y/∂ρ = (1/ρ_half) Σ_k k θ^(k−1) Y_k (zero for a constant Y)."""
        derivative = _values_at(self.Y_k, self.scaling.theta(rho), self.scaling.rho_half)[1]
        return np.zeros_like(self.Y_k[0]) if derivative is None else derivative

    def controller(self, rho, rho_dot, plant_point=None, rate_term=None):
        """Continuous controller (A_K, B_K, C_K, D_K), u = K y on the original channels (§4).

        Parameters
        ----------
        rho, rho_dot : float
            Scheduling value and its rate. A_K is affine in ρ̇; it does not depend on ρ̇ for the
            quadratic and the ``x_constant`` variants.
        plant_point : PlantPoint or tuple, optional
            The original plant at ρ. When given, K is reconstructed exactly at ρ; otherwise K
            is the exact controller at a grid value or the linear interpolation, in ρ, of the
            two neighbouring grid controllers, with ρ clipped to the grid range (as in the
            thesis' simulations, docs/LPV_SYNTHESIS.md §6).
        rate_term : np.ndarray, optional
            With ``plant_point``: the plant's rate term N(ρ) (original coordinates), so that
            K is reconstructed for A + ρ̇ N as at the grid points of a plant with a rate term.
        """
        if plant_point is not None:
            if not isinstance(plant_point, PlantPoint):
                plant_point = PlantPoint(*plant_point, *self.sizes)
            point = self.scaling.normalise(plant_point)
            if rate_term is not None:
                point = _shifted(point, rho_dot * self.scaling.T_inv @ rate_term @ self.scaling.T)
            return self._controller_at_point(point, rho, rho_dot)
        rho = float(np.clip(rho, self.rho[0], self.rho[-1]))
        upper = int(np.searchsorted(self.rho, rho))
        if self.rho[min(upper, self.rho.size - 1)] == rho:
            return self._controller_at_point(self._grid_point(upper, rho_dot), rho, rho_dot)
        lower = upper - 1
        weight = (rho - self.rho[lower]) / (self.rho[upper] - self.rho[lower])
        K_lower = self._controller_at_point(self._grid_point(lower, rho_dot), self.rho[lower],
                                            rho_dot)
        K_upper = self._controller_at_point(self._grid_point(upper, rho_dot), self.rho[upper],
                                            rho_dot)
        return tuple((1.0 - weight) * a + weight * b for a, b in zip(K_lower, K_upper))

    def _grid_point(self, i, rho_dot):
        """Normalised plant of grid point i at the rate ρ̇ (A + ρ̇ N when there is a rate term)."""
        if not self.rate_A:
            return self.points[i]
        return _shifted(self.points[i], rho_dot * self.rate_A[i])

    def _controller_at_point(self, point, rho, rho_dot):
        return controller_at(point, self.X(rho), self.Y(rho), rho_dot * self.dX_drho(rho),
                             self.gamma)


def _shifted(point, dA):
    """The normalised point with A + dA (Â, Ã follow: B2, C2 are unchanged)."""
    return replace(point, A=point.A + dA)


def _lmi_x_blocks(p, X, X_dot, g):
    """Blocks of LMI-X (§2) for numpy arrays or cvxpy expressions; X_dot = ∂X[ν] or None."""
    n_e1, n_w = p.n_e1, p.B1.shape[1]
    Phi = p.A_hat @ X + X @ p.A_hat.T - p.B2 @ p.B2.T    # ÂX + XÂᵀ − B2B2ᵀ
    if X_dot is not None:
        Phi = Phi - X_dot                                 # − ∂X[ν]
    if n_e1 == 0:
        return [[Phi, g * p.B_hat], [g * p.B_hat.T, -np.eye(n_w)]]
    return [[Phi, X @ p.C11.T, g * p.B_hat],
            [p.C11 @ X, -np.eye(n_e1), g * p.D_r],
            [g * p.B_hat.T, g * p.D_r.T, -np.eye(n_w)]]


def _lmi_y_blocks(p, Y, Y_dot, g):
    """Blocks of LMI-Y (§2) for numpy arrays or cvxpy expressions; Y_dot = ∂Y[ν] or None."""
    n_w1, n_e = p.n_w1, p.C1.shape[0]
    Phi = Y @ p.A_tilde + p.A_tilde.T @ Y - p.C2.T @ p.C2    # YÃ + ÃᵀY − C2ᵀC2
    if Y_dot is not None:
        Phi = Phi + Y_dot                                        # + ∂Y[ν]
    if n_w1 == 0:
        return [[Phi, g * p.C_tilde.T], [g * p.C_tilde, -np.eye(n_e)]]
    return [[Phi, Y @ p.B11, g * p.C_tilde.T],
            [p.B11.T @ Y, -np.eye(n_w1), g * p.D_c.T],
            [g * p.C_tilde, g * p.D_c, -np.eye(n_e)]]


@dataclass(frozen=True)
class _Layout:
    """Where the LMIs are imposed: normalised points, θ_i, basis sizes, rate vertices."""

    points: tuple
    theta: np.ndarray
    rho_half: float
    n_X: int                  # number of basis functions of X (1 or 3)
    n_Y: int
    vertices: tuple           # rate vertices ν (empty: no rate terms)
    riccati_balanced: bool    # plant_scaling applied the Riccati balancing
    rate_A: tuple = ()        # the plant's rate term per point, balanced coordinates (or empty)

    def point_at(self, i, nu):
        """Normalised point i at the rate vertex ν (A + ν N with a rate term)."""
        p = self.points[i]
        return p if nu is None or not self.rate_A else _shifted(p, nu * self.rate_A[i])

    def rate_terms(self, n_basis):
        """The rate vertices for a variable with n_basis functions, or (None,) if constant
        (and the plant has no rate term)."""
        return self.vertices if (n_basis > 1 or self.rate_A) and self.vertices else (None,)

    def lmi_scales(self):
        """LMI scales for the strictness margin: max(1, ‖B2B2ᵀ‖), max(1, ‖C2ᵀC2‖)."""
        s_X = max([1.0] + [np.linalg.norm(p.B2, 2) ** 2 for p in self.points])
        s_Y = max([1.0] + [np.linalg.norm(p.C2, 2) ** 2 for p in self.points])
        return s_X, s_Y


def _values_at(coefficients, theta_i, rho_half):
    """(Σ_k θ^k C_k, ∂/∂ρ of it or None if constant) for cvxpy variables or numpy arrays."""
    value = coefficients[0]
    derivative = None
    for k in range(1, len(coefficients)):
        value = value + theta_i ** k * coefficients[k]
        term = (k * theta_i ** (k - 1) / rho_half) * coefficients[k]
        derivative = term if derivative is None else derivative + term
    return value, derivative


def _rate(derivative, nu):
    """∂[ν] = ν ∂/∂ρ, or None without rate terms."""
    return None if nu is None or derivative is None else nu * derivative


def _all_lmis(layout, Xk, Yk, g):
    """Every LMI-X and LMI-Y of §2 with what its margins need, plus (X(ρ_i), Y(ρ_i)) per grid
    point; for cvxpy expressions or numpy arrays.

    Each LMI comes as (block list, V, W, s): its Lyapunov variable V (X or Y), the constant PSD
    matrix W of its first block (B2B2ᵀ or C2ᵀC2) and the scale s = max(1, max_i ‖W_i‖).
    """
    s_X, s_Y = layout.lmi_scales()
    lmis, XY = [], []
    for i, (p, theta_i) in enumerate(zip(layout.points, layout.theta)):
        X, dX = _values_at(Xk, theta_i, layout.rho_half)
        Y, dY = _values_at(Yk, theta_i, layout.rho_half)
        XY.append((X, Y))
        for nu in layout.rate_terms(layout.n_X):
            lmis.append((_lmi_x_blocks(layout.point_at(i, nu), X, _rate(dX, nu), g), X,
                         p.B2 @ p.B2.T, s_X))
        for nu in layout.rate_terms(layout.n_Y):
            lmis.append((_lmi_y_blocks(layout.point_at(i, nu), Y, _rate(dY, nu), g), Y,
                         p.C2.T @ p.C2, s_Y))
    return lmis, XY


def _with_margin(blocks, V, W, scale, eps, tau=0.0):
    """Blocks of LMI + margin; ``LMI + margin ≤ 0`` is the constraint.

    margin = ε·diag(V + s·I, I, …) + τ·diag(W + V/4, I, …):

    - ε (§3, both stages) makes the LMI strict above the solver's error: relative to the
      Lyapunov variable V (a decay-rate margin of ε/2, invariant under state scaling, since the
      solver's absolute error grows with ‖V‖) and to the scale s of the constant term;
    - τ (stage 2 only) is a robustness margin: the LMI then still holds with the control
      (W = B2B2ᵀ) or measurement (W = C2ᵀC2) term shrunk by the factor 1 − τ, the performance
      channels tightened by τ and the decay rate raised by τ/8 (kept small: uncontrollable or
      unobservable weight modes slower than that make the margin infeasible). It keeps the
      certificate negative between grid points, where the plain stage 2 (every LMI active at
      the grid points) fails even for smooth plants.
    """
    out = [list(row) for row in blocks]
    n = blocks[0][0].shape[0]
    out[0][0] = out[0][0] + eps * (V + scale * np.eye(n))
    if tau:
        out[0][0] = out[0][0] + tau * (W + 0.25 * V)
    for k in range(1, len(out)):
        out[k][k] = out[k][k] + (eps + tau) * np.eye(out[k][k].shape[0])
    return out


def _schur_last(blocks):
    """Schur complement on a constant last block −cI whose row holds constants only.

    [[P, Q], [Qᵀ, −cI]] ≤ 0 ⟺ P + QQᵀ/c ≤ 0 (c > 0): the same constraint, one block smaller;
    linear in the variables when g is fixed (stage 2).
    """
    c = -blocks[-1][-1][0, 0]
    last_col = [row[-1] for row in blocks[:-1]]
    return [[blocks[i][j] + last_col[i] @ last_col[j].T / c for j in range(len(blocks) - 1)]
            for i in range(len(blocks) - 1)]


def _lmi_constraints(layout, Xk, Yk, g, eps, reduce, tau=0.0):
    """cvxpy constraints LMI-X, LMI-Y (with margins) at every (ρ_i, ν); X(ρ_i), Y(ρ_i) per point."""
    lmis, XY = _all_lmis(layout, Xk, Yk, g)
    constraints = []
    for blocks, V, W, scale in lmis:
        blocks = _with_margin(blocks, V, W, scale, eps, tau)
        if reduce:
            blocks = _schur_last(blocks)
        constraints.append(cp.bmat(blocks) << 0)                  # LMI(ρ_i, ν) + margin ≤ 0
    return constraints, XY


def _solve(problem, solver, layout, embedding=False):
    """Solve with ``solver``; return (status, solver time, iterations), never raising.

    ``embedding`` (IPM only): solve on the homogeneous self-dual embedding
    (sdp_ipm.solve_conic_hsde) instead of the infeasible-start iteration (sdp_ipm.solve_conic).

    Clarabel settings that depend on the problem: no Ruiz equilibration when the plant is
    Riccati-balanced (equilibrating on top of it made Clarabel stop at iteration 0 with a
    numerical error at 3 of the 9 grid points of the VEGA weighted plant, and with it off all
    9 points match sb10ad within 1.1 %); single-threaded for small plants (n < 12), where
    threads do not pay and only add to the contention on a loaded two-core machine. After a
    Clarabel solver error one more attempt is made with a larger static KKT regularisation
    (``_CLARABEL_RETRY_REGULARISATIONS``).
    """
    options = dict(_SOLVER_OPTIONS.get(solver, {}))
    retries = []
    if solver == "CLARABEL":
        options["equilibrate_enable"] = not layout.riccati_balanced
        if layout.points[0].n_x < 12:
            options["max_threads"] = 1
        retries = [dict(options, static_regularization_constant=value)
                   for value in _CLARABEL_RETRY_REGULARISATIONS]
    if solver == IPM:
        return _solve_ipm(problem, embedding)
    for attempt in [options] + retries:
        try:
            with warnings.catch_warnings():
                # "Solution may be inaccurate": such answers go through the independent checks
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                problem.solve(solver=solver, **attempt)
            break
        except cp.error.SolverError:
            continue
    else:
        return "solver_error", float("nan"), 0
    stats = problem.solver_stats
    return problem.status, stats.solve_time or float("nan"), stats.num_iters or 0


def _solve_ipm(problem, embedding=False):
    """Solve with sdp_ipm.solve_conic (or solve_conic_hsde with ``embedding``) on cvxpy's
    Clarabel canonicalisation; never raising."""
    try:
        data, chain, inverse = problem.get_problem_data(cp.CLARABEL)
        dims = data["dims"]
        if dims.zero or dims.soc or dims.exp or getattr(dims, "p3d", None):
            return "solver_error", float("nan"), 0
        if embedding:
            # stage 2 maximises a conditioning margin t: its optimum need not be reached, a
            # primal feasible answer (residual 1e-7) within 1 % of it serves, and is checked
            # independently. On the 9-point problem the normal equations stalled at a relative
            # gap of 1.5e-3 (dual residual 3e-5) after 41 iterations; 1 % was reached at 32.
            answer = solve_conic_hsde(data["A"], data["b"], data["c"], dims.psd, dims.nonneg,
                                      tol_gap_rel=1e-2, tol_dual=1e-3, reduced_tol=1e-2)
        else:
            # centring floor 0.3 after short steps: without it stage 1 of the 26-point grid
            # stalled at a relative gap of 1.8 %; with it, 2.2e-4 (docs/SYNTHESIS.md §8)
            answer = solve_conic(data["A"], data["b"], data["c"], dims.psd, dims.nonneg,
                                 centring_floor=0.3)
        inverse[-1].solver_options = {}
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Solution may be inaccurate")
            problem.unpack_results(answer, chain, inverse)
    except (cp.error.SolverError, ValueError, np.linalg.LinAlgError):
        return "solver_error", float("nan"), 0
    return problem.status, answer.solve_time, answer.iterations


def _check_lmis(layout, Xk, Yk, g):
    """Largest eigenvalue over all LMIs (coupling as −[X, gI; gI, Y]) evaluated in numpy."""
    lmis, XY = _all_lmis(layout, Xk, Yk, g)
    worst = -np.inf
    for blocks, *_ in lmis:
        L = np.block(blocks)
        worst = max(worst, np.linalg.eigvalsh(0.5 * (L + L.T))[-1])
    for X, Y in XY:
        n = X.shape[0]
        coupling = np.block([[X, g * np.eye(n)], [g * np.eye(n), Y]])
        worst = max(worst, -np.linalg.eigvalsh(0.5 * (coupling + coupling.T))[0])
    return float(worst)


def _coupling(X, Y, g, eps, n):
    """[X, gI; gI, Y] − ε·diag(X + gI, Y + gI) (the coupling condition with its margin)."""
    I_n = np.eye(n)
    return cp.bmat([[(1.0 - eps) * X - eps * g * I_n, g * I_n],
                    [g * I_n, (1.0 - eps) * Y - eps * g * I_n]])


def _variables(layout, n):
    """Coefficient matrices X_k, Y_k (symmetric cvxpy variables)."""
    return ([cp.Variable((n, n), symmetric=True, name=f"X{k}") for k in range(layout.n_X)],
            [cp.Variable((n, n), symmetric=True, name=f"Y{k}") for k in range(layout.n_Y)])


@dataclass(frozen=True)
class _Attempt:
    """One solver run of one stage: status, solver statistics and the checked answer."""

    solver: str
    status: str
    solve_time_s: float
    iterations: int
    answer: tuple = None          # (X_k, Y_k, g or t) when the status is acceptable
    lmi_max_eig: float = float("nan")

    def describe(self):
        return f"{self.solver}: {self.status}, max LMI eig {self.lmi_max_eig:.3g}"


def _distinct(layout, XY):
    """The (X(ρ_i), Y(ρ_i)) pairs that differ: one pair when X and Y are both constant.

    Imposing the same coupling (or bound) constraint once per grid point would repeat an
    identical PSD cone, which makes the interior-point KKT system singular (Clarabel stops
    with a numerical error at its first iteration on the quadratic variant).
    """
    return XY[:1] if layout.n_X == 1 and layout.n_Y == 1 else XY


def _lmi_constraints_g2(layout, Xk, Yk, h, eps):
    """Stage-1 LMIs in the Schur-reduced form, linear in h ≥ g² (docs/SYNTHESIS.md §8).

    With g free, the last block row of LMI-X, LMI-Y is g·[B̂ᵀ, D_rᵀ, −I/g] (resp. g·[C̃, D_c, ·]):
    the Schur complement on its constant block −cI gives P(V) + g²·qqᵀ/c ≤ 0 with qqᵀ ⪰ 0, so
    with an auxiliary h ≥ g² (a 2×2 PSD cone [h, g; g, 1] ⪰ 0) the set of (X, Y, g) is the same
    (take h = g²) and every LMI loses its n_w (resp. n_e) last rows: 33 → 24 and 30 → 24 on
    the VEGA plant.
    """
    lmis, XY = _all_lmis(layout, Xk, Yk, 1.0)
    constraints = []
    for blocks, V, W, scale in lmis:
        blocks = _with_margin(blocks, V, W, scale, eps)
        c = -blocks[-1][-1][0, 0]
        last = [row[-1] for row in blocks[:-1]]      # the g = 1 column: constants
        size = len(blocks) - 1
        constraints.append(cp.bmat([[blocks[i][j] + h * (last[i] @ last[j].T / c)
                                     for j in range(size)] for i in range(size)]) << 0)
    return constraints, XY


def _stage1(layout, n, eps, regularisation, solver, form="reduced"):
    """Stage 1 (§3): maximise g − δ·mean_i tr(X(ρ_i) + Y(ρ_i))/(2n) subject to the LMIs of §2.

    ``form``: "reduced" (default) imposes the LMIs Schur-reduced with h ≥ g²
    (``_lmi_constraints_g2``), "full" in their 3×3-block form (the "clarabel" solver path,
    ``pipeline.SOLVER_PATHS``).
    """
    Xk, Yk = _variables(layout, n)
    g = cp.Variable(name="g")
    if form == "full":
        constraints, XY = _lmi_constraints(layout, Xk, Yk, g, eps, reduce=False)
    else:
        h = cp.Variable(name="h")
        constraints, XY = _lmi_constraints_g2(layout, Xk, Yk, h, eps)
        constraints.append(cp.bmat([[h, g], [g, 1.0]]) >> 0)      # h ≥ g²
    constraints.append(g >= 0.0)
    XY = _distinct(layout, XY)
    for X, Y in XY:
        constraints.append(_coupling(X, Y, g, eps, n) >> 0)   # [X, gI; gI, Y] > 0 (with margin)
    trace = sum(cp.trace(X) + cp.trace(Y) for X, Y in XY) / (2 * n * len(XY))
    problem = cp.Problem(cp.Maximize(g - regularisation * trace), constraints)
    status, solve_time, iterations = _solve(problem, solver, layout)
    if status not in _ACCEPTED_STATUSES or g.value is None or not g.value > 0.0:
        return _Attempt(solver, status, solve_time, iterations)
    Xv, Yv, gv = [x.value for x in Xk], [y.value for y in Yk], float(g.value)
    return _Attempt(solver, status, solve_time, iterations, (Xv, Yv, gv),
                    _check_lmis(layout, Xv, Yv, gv))


def _stage2(layout, n, eps, g, bound, solver, robustness):
    """Stage 2 (§3): g fixed; [X − tI, gI; gI, Y] > 0, t ≥ 0, X, Y ≤ cI; maximise t.

    With g fixed the last block row of LMI-X and LMI-Y is constant, and they enter in their
    Schur-complemented form (one block smaller, same constraint). ``robustness`` is the margin
    τ of :func:`_with_margin`; 0 gives the plain stage 2 of docs/LPV_SYNTHESIS.md §3.
    """
    Xk, Yk = _variables(layout, n)
    t = cp.Variable(name="t")
    constraints, XY = _lmi_constraints(layout, Xk, Yk, g, eps, reduce=True, tau=robustness)
    constraints.append(t >= 0.0)
    I_n = np.eye(n)
    for X, Y in _distinct(layout, XY):
        constraints.append(_coupling(X - t * I_n, Y, g, eps, n) >> 0)   # [X − tI, gI; gI, Y] > 0
        constraints.append(X << bound * I_n)                              # X ≤ cI
        constraints.append(Y << bound * I_n)                              # Y ≤ cI
    problem = cp.Problem(cp.Maximize(t), constraints)
    # IPM: the embedding; the infeasible-start iteration stalled here (docs/SYNTHESIS.md §8)
    status, solve_time, iterations = _solve(problem, solver, layout, embedding=True)
    if status not in _ACCEPTED_STATUSES or t.value is None:
        return _Attempt(solver, status, solve_time, iterations)
    Xv, Yv = [x.value for x in Xk], [y.value for y in Yk]
    return _Attempt(solver, status, solve_time, iterations, (Xv, Yv, float(t.value)),
                    _check_lmis(layout, Xv, Yv, g))


def _check_arguments(plant, rate_bounds, basis, backoff, eps):
    """Validate the arguments of :func:`synthesize`; return the rate vertices."""
    if not isinstance(plant, GriddedPlant):
        raise PlantDataError("plant must be a GriddedPlant")
    if basis not in ("quadratic", "constant"):
        raise ValueError(f"basis must be 'quadratic' or 'constant', got {basis!r}")
    if not backoff >= 1.0:
        raise ValueError(f"backoff must be >= 1, got {backoff!r}")
    if not eps > 0.0:
        raise ValueError(f"eps must be positive, got {eps!r}")
    if rate_bounds is None:
        return ()
    lo, hi = (float(v) for v in rate_bounds)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"rate_bounds must be finite with lo <= hi, got {rate_bounds!r}")
    if basis == "quadratic" and plant.n_grid < 3:
        raise ValueError("a quadratic basis with rate bounds needs at least 3 grid points")
    return (lo,) if lo == hi else (lo, hi)


def synthesize(plant, rate_bounds=None, basis="quadratic", x_constant=False, backoff=1.2,
               solver="CLARABEL", fallback="SCS", eps=1e-6, regularisation=1e-6,
               bound=1e2, robustness=3e-2, balance="riccati", stage1_form="full",
               stage2_solvers=None):
    """Rate-bounded LPV H∞ output-feedback synthesis on a grid (docs/LPV_SYNTHESIS.md §1–§5).

    Parameters
    ----------
    plant : GriddedPlant
        Generalised plant, inputs [w; u], outputs [e; y]; D12 full column rank and D21 full
        row rank at every grid point.
    rate_bounds : (float, float) or None
        Box lo ≤ ρ̇ ≤ hi; its two ends are the rate vertices (ρ̇ = 0 is not one unless it is an
        end). None gives the quadratic variant: constant X and Y, valid for arbitrary ρ̇.
    basis : {"quadratic", "constant"}
        Basis of X(ρ), Y(ρ): [1, θ, θ²] or [1]. Ignored (constant) when rate_bounds is None.
        A single grid point with "constant" is the LTI H∞ problem.
    x_constant : bool
        Keep X constant (Y parameter-dependent): the controller does not depend on ρ̇.
    backoff : float
        Stage 2 fixes γ = backoff·γ_1; 1 skips stage 2 (controller at γ_1).
    solver : str
        A cvxpy solver name ("CLARABEL", the default: the path that produced the shipped
        table), or "IPM": the interior-point method of sdp_ipm.py (normal equations; stage 1
        by the infeasible-start iteration, stage 2 on the self-dual embedding; verified on
        the shipped 26-point grid with its dense certificate, docs/SYNTHESIS.md §8).
    fallback : str, tuple of str or None
        Solvers tried in turn when the first answer is not accepted (None: no fallback).
    eps : float
        Relative strictness margin ε of the LMIs (§3): LMI + ε·diag(V + sI, I, …) ≤ 0 with V the
        Lyapunov variable and s the scale of the constant term; coupling ≥ ε·diag(X + gI, Y + gI).
    regularisation : float
        Weight δ of the stage-1 regulariser δ·mean_i tr(X(ρ_i) + Y(ρ_i))/(2n).
    bound : float
        Stage-2 bound c on X and Y (raised to the stage-1 peak if that is larger, so that the
        stage-1 answer stays feasible).
    robustness : float
        Stage-2 robustness margin τ (``_with_margin``: control/measurement terms × (1 − τ),
        performance channels tightened by τ, decay rate +τ/8). Without it every stage-2 LMI is
        active at the grid points and the certificate fails between them even for smooth
        plants. If this stage 2 is infeasible, the plain one (τ = 0, feasible by construction)
        is solved; 0 gives the plain stage 2 directly.
    balance : {"riccati", "diagonal"}
        State balancing of the pre-processing (plant_scaling.py).
    stage1_form : {"reduced", "full"}
        Stage-1 LMIs in the 3×3-block form (default, the shipped table's path) or
        Schur-reduced with h ≥ g² (smaller cones, ≈ 1.6× faster per Clarabel iteration on 3
        points; the same feasible set).
    stage2_solvers : tuple of str, optional
        Solvers for stage 2 in turn (default: ``solver`` and ``fallback``, as stage 1); e.g.
        Clarabel for stage 1 and the IPM for stage 2 (pipeline.SOLVER_PATHS["hybrid"], the
        answer to the IPM's stage-1 stall on 26 points before its centring floor;
        docs/SYNTHESIS.md §8).

    Returns
    -------
    LpvSynthesisResult

    Raises
    ------
    PlantDataError
        Malformed plant or rank-deficient D12/D21.
    SynthesisError
        No solver answer passed the independent checks.
    """
    vertices = _check_arguments(plant, rate_bounds, basis, backoff, eps)
    scaling = plant_scaling(plant, balance=balance)
    points = tuple(scaling.normalise(plant.point(i)) for i in range(plant.n_grid))
    varying = bool(vertices) and basis == "quadratic"
    # the plant's rate term (GriddedPlant.N) in the balanced coordinates; it enters the LMIs at
    # the rate vertices only (the quadratic variant, for arbitrary ρ̇, leaves it out)
    rate_A = (tuple(scaling.T_inv @ N_i @ scaling.T for N_i in plant.N)
              if plant.N is not None and varying else ())
    layout = _Layout(points=points, theta=scaling.theta(plant.rho), rho_half=scaling.rho_half,
                     n_X=3 if varying and not x_constant else 1, n_Y=3 if varying else 1,
                     vertices=vertices if varying else (),
                     riccati_balanced=scaling.balance == "riccati", rate_A=rate_A)
    if stage1_form not in ("reduced", "full"):
        raise ValueError(f"stage1_form must be 'reduced' or 'full', got {stage1_form!r}")
    fallbacks = (fallback,) if isinstance(fallback, str) else tuple(fallback or ())
    solvers = [name for name in (solver, *fallbacks) if name]
    n = plant.n_x
    check_rates = layout.vertices or (0.0,)
    record = {"times_s": {}, "statuses": {}, "solvers": {}, "lmi_max_eig": {}}

    def accept(stage, attempt, elapsed):
        record["times_s"][stage] = elapsed
        record["times_s"][stage + "_solver"] = attempt.solve_time_s
        record["times_s"][stage + "_iterations"] = attempt.iterations
        record["statuses"][stage] = attempt.status
        record["solvers"][stage] = attempt.solver
        record["lmi_max_eig"][stage] = attempt.lmi_max_eig

    def result_for(Xk, Yk, gamma, t_margin):
        return LpvSynthesisResult(
            gamma_min=gamma_min, gamma=gamma, X_k=tuple(Xk), Y_k=tuple(Yk),
            rate_vertices=layout.vertices, scaling=scaling, points=points, rho=plant.rho.copy(),
            rate_A=layout.rate_A,
            sizes=(plant.n_w, plant.n_u, plant.n_e, plant.n_y), t_margin=t_margin)

    def certified(result):
        rate_term = None
        if layout.rate_A:
            def rate_term(rho):
                return plant.N[int(np.argmin(np.abs(plant.rho - rho)))]
        return float(np.max(certificate_check(plant, result, plant.rho, check_rates,
                                              rate_term=rate_term)))

    # Stage 1: minimum γ
    start, tried = time.perf_counter(), []
    for name in solvers:
        attempt = _stage1(layout, n, eps, regularisation, name, stage1_form)
        tried.append(attempt.describe())
        if attempt.answer and attempt.lmi_max_eig < 0.0:
            break
    else:
        raise SynthesisError("stage 1 failed (" + "; ".join(tried) + ")")
    accept("stage1", attempt, time.perf_counter() - start)
    X1, Y1, g1 = attempt.answer
    gamma_min = 1.0 / g1

    if backoff == 1.0:
        result = result_for(X1, Y1, gamma_min, float("nan"))
        certificate = certified(result)
        if not certificate < 0.0:
            raise SynthesisError(f"stage-1 controller fails the certificate ({certificate:.3g})")
        return replace(result, certificate_max_eig=certificate, **record)

    # Stage 2: back-off at γ = backoff·γ_1, well-conditioned X, Y
    g2 = 1.0 / (backoff * gamma_min)
    peak = max(np.linalg.eigvalsh(M)[-1] for M in itertools.chain.from_iterable(
        _all_lmis(layout, X1, Y1, g1)[1]))
    c = max(bound, 1.01 * peak)
    start, tried = time.perf_counter(), []
    # The in-house IPM solves stage 2 on the homogeneous self-dual embedding (its infeasible-
    # start iteration stalled there: primal residual ≈ 0.07, dual objective growing as for an
    # infeasibility certificate; docs/SYNTHESIS.md §8).
    stage2_solvers = list(stage2_solvers) if stage2_solvers else solvers
    # the robustness margin with each interior-point solver first (not with SCS, whose answers
    # rarely pass), then the plain stage 2 with each solver
    variants = [(name, robustness) for name in stage2_solvers
                if robustness > 0.0 and name != "SCS"]
    variants += [(name, 0.0) for name in stage2_solvers]
    for name, tau in variants:
        attempt = _stage2(layout, n, eps, g2, c, name, tau)
        certificate = float("nan")
        if attempt.answer and attempt.lmi_max_eig < 0.0:
            Xk, Yk, t_margin = attempt.answer
            result = result_for(Xk, Yk, 1.0 / g2, t_margin)
            certificate = certified(result)
        tried.append(f"{attempt.describe()} (robustness {tau:g}), certificate {certificate:.3g}")
        if certificate < 0.0:
            break
    else:
        raise SynthesisError("stage 2 failed (" + "; ".join(tried) + ")")
    accept("stage2", attempt, time.perf_counter() - start)
    return replace(result, certificate_max_eig=certificate, robustness=tau, **record)
