"""Frozen-point LTI study: the optimal H∞ γ of M(ρ_i) at each grid point.

At each grid point the LTI problem min_K ‖F_l(M(ρ_i), K)‖∞ is solved with SLICOT sb10ad
(the routine behind python-control's ``hinfsyn``; Glover–Doyle formulas) on a
state-balanced realisation of M, γ_opt by bisection on sb10ad's admissibility test. Its
γ_i are lower bounds of the LPV γ (docs/LPV_SYNTHESIS.md §5: any LPV controller frozen at ρ_i
is one LTI candidate); max_i γ_i ≤ ~0.8 leaves room for the LPV cost of a rate-bounded,
parameter-dependent Lyapunov function (γ_LPV typically 1.0–1.2×).

Every γ_i is checked independently: sb10ad's central controller at 1.01·γ_opt is closed
around the *unbalanced* M with
:meth:`~vega_lpv.interconnection.GeneralizedPlant.close_loop`, the closed loop must
be stable, and its H∞ norm is computed twice — by ``control.norm`` (SLICOT ab13dd) and by a
dense frequency sweep refined at the lightly damped poles.

Run ``python -m vega_lpv.frozen_point [--details]`` for the tables of
docs/SYNTHESIS_WEIGHTS.md §5.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, replace

import numpy as np

from vega_model.parameters import ModelContext

from vega_lpv.interconnection import GRID_TIMES_S, GeneralizedPlant, weighted_plant
from vega_lpv.weights import SHIPPED, SINGLE_RELAXATIONS, THESIS, WeightSet

__all__ = ["FrozenPointResult", "state_scaling", "balanced", "optimal_gamma",
           "frozen_point_gamma", "lti_study", "hinf_norm_sweep", "study_variants"]


@dataclass(frozen=True)
class FrozenPointResult:
    """γ of one frozen grid point and its independent checks.

    Attributes
    ----------
    t_s, rho_mps
        Grid point (flight time [s], ρ = v [m/s]).
    gamma
        γ_opt: the smallest γ found admissible by sb10ad (:func:`optimal_gamma`).
    gamma_refused
        The largest γ refused (γ_opt/γ_refused ≤ 1 + 1e-4).
    gamma_check
        H∞ norm by ab13dd (``control.norm(..., 'inf')``) of F_l(M, K) with the central
        controller K at (1 + margin)·γ_opt.
    gamma_sweep
        Peak of σ_max of that closed loop over a frequency sweep (a lower bound).
    peak_radps
        Frequency of that peak [rad/s].
    stable
        All poles of that closed loop in the open left half-plane.
    """

    t_s: float
    rho_mps: float
    gamma: float
    gamma_refused: float
    gamma_check: float
    gamma_sweep: float
    peak_radps: float
    stable: bool


def state_scaling(A, B, C, iterations: int = 100) -> np.ndarray:
    """Diagonal state scaling d (x = diag(d) x̃) that balances [A B; C ·] (Osborne).

    Parameters
    ----------
    A, B, C
        State-space matrices (D is not affected by a state similarity).
    iterations
        Maximum number of sweeps.

    Returns
    -------
    numpy.ndarray
        d > 0, powers of two (exact in floating point). In the scaled coordinates
        Ã = D⁻¹AD, B̃ = D⁻¹B, C̃ = CD, the 2-norm of row i of [Ã B̃] (off-diagonal part of
        Ã) equals that of column i of [Ã; C̃] to within a factor of 2.

    Notes
    -----
    The idea of MATLAB's ``ssbal`` (Osborne/``gebal`` iteration on [A B; C 0]) applied to
    the state rows and columns only, so transfer functions, the closed loop and γ are
    unchanged.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    C = np.asarray(C, dtype=float)
    n = A.shape[0]
    log_d = np.zeros(n)
    for _ in range(iterations):
        changed = False
        for i in range(n):
            d = np.exp2(log_d)
            row = np.concatenate([np.delete(A[i], i) * np.delete(d, i) / d[i], B[i] / d[i]])
            col = np.concatenate([np.delete(A[:, i], i) * d[i] / np.delete(d, i), C[:, i] * d[i]])
            r, c = np.linalg.norm(row), np.linalg.norm(col)
            if r == 0.0 or c == 0.0:
                continue
            step = round(0.5 * math.log2(r / c))
            if step != 0:
                log_d[i] += step
                changed = True
        if not changed:
            break
    return np.exp2(log_d)


def balanced(plant: GeneralizedPlant) -> GeneralizedPlant:
    """``plant`` in state-balanced coordinates (:func:`state_scaling`); names unchanged."""
    d = state_scaling(plant.A, plant.B, plant.C)
    return replace(plant, A=plant.A * d[None, :] / d[:, None], B=plant.B / d[:, None],
                   C=plant.C * d[None, :])


def hinf_norm_sweep(A, B, C, D, n_points: int = 2000) -> tuple[float, float]:
    """Peak σ_max(C (jωI − A)⁻¹ B + D) over a frequency sweep, and its frequency [rad/s].

    The grid is logarithmic over 1e-5…1e5 rad/s plus, for every lightly damped pole
    λ, a fine grid of ±5·|Re λ| around |Im λ|; the sweep value is a lower bound of the
    H∞ norm that is tight when the grid resolves the peak.
    """
    n = A.shape[0]
    poles = np.linalg.eigvals(A)
    w = [np.logspace(-5, 5, n_points)]
    for lam in poles:
        if lam.imag > 0 and abs(lam.real) < 0.2 * abs(lam):
            w.append(lam.imag + abs(lam.real) * np.linspace(-5.0, 5.0, 41))
    w = np.unique(np.abs(np.concatenate(w)))
    eye = np.eye(n)
    best, best_w = float(np.linalg.svd(C @ np.linalg.solve(-A, B) + D, compute_uv=False)[0]), 0.0
    for wk in w:
        g = C @ np.linalg.solve(1j * wk * eye - A, B) + D
        s = np.linalg.svd(g, compute_uv=False)[0]
        if s > best:
            best, best_w = float(s), float(wk)
    return best, best_w


def _sb10ad(plant: GeneralizedPlant, gamma: float, job: int):
    """SLICOT sb10ad on ``plant``: (γ, (Ak, Bk, Ck, Dk)); raises on failure."""
    from slycot import sb10ad

    out = sb10ad(plant.n_x, plant.n_w + plant.n_u, plant.n_e + plant.n_y, plant.n_u,
                 plant.n_y, gamma, plant.A, plant.B, plant.C, plant.D, job=job)
    return float(out[0]), out[1:5]


def _admissible(plant: GeneralizedPlant, gamma: float):
    """Central controller at ``gamma`` (sb10ad job 4), or None if sb10ad refuses it."""
    try:
        return _sb10ad(plant, gamma, job=4)[1]
    except Exception:  # noqa: BLE001 - slycot: SlycotArithmeticError (info 6-8, 12) when γ is too small
        return None


def optimal_gamma(plant: GeneralizedPlant, rtol: float = 1e-4) -> tuple[float, float]:
    """Bracket [γ_lo, γ_hi] of the optimal LTI γ by bisection on sb10ad's admissibility.

    γ_hi is admissible (sb10ad job 4 returns a stabilising central controller), γ_lo is
    refused, γ_hi/γ_lo ≤ 1 + rtol. ``plant`` should be balanced (:func:`balanced`).

    Raises
    ------
    RuntimeError
        If no admissible γ ≤ 1e6 exists (or the plant violates sb10ad's assumptions).
    """
    g = 1.0
    if _admissible(plant, g) is not None:
        while _admissible(plant, g / 2.0) is not None and g > 1e-6:
            g /= 2.0
        hi, lo = g, g / 2.0
    else:
        while _admissible(plant, 2.0 * g) is None:
            g *= 2.0
            if g > 1e6:
                raise RuntimeError(f"no admissible γ ≤ 1e6 at t = {plant.t_s:g} s")
        hi, lo = 2.0 * g, g
    while hi / lo > 1.0 + rtol:
        mid = math.sqrt(hi * lo)
        if _admissible(plant, mid) is not None:
            hi = mid
        else:
            lo = mid
    return lo, hi


def frozen_point_gamma(plant: GeneralizedPlant, margin: float = 0.01) -> FrozenPointResult:
    """Optimal LTI γ of one frozen grid point, with independent checks.

    Parameters
    ----------
    plant
        The generalised plant M(ρ_i)
        (e.g. :func:`~vega_lpv.interconnection.weighted_plant`).
    margin
        The checked controller is sb10ad's central controller at (1 + margin)·γ_opt.

    Returns
    -------
    FrozenPointResult

    Notes
    -----
    γ_opt is found by :func:`optimal_gamma` on the state-balanced M rather than by
    ``control.hinfsyn``: hinfsyn starts sb10ad at γ = 1e100 with bisection *and* scan
    (job 3), whose scan stalled for more than 10 minutes on some weight sets; bisection on
    the same routine's admissibility test gives the same γ (tests/synthesis/test_interconnection.py
    compares them) in ~0.1 s. The controller at γ_opt itself is nearly singular (closed-loop
    poles → 0, ill-conditioned Riccati solutions), so the check closes the central
    controller at (1 + margin)·γ_opt around the *unbalanced* M: it must be stable with
    γ_opt ≤ ‖F_l(M, K)‖∞ ≤ (1 + margin)·γ_opt.
    """
    import control

    pb = balanced(plant)
    lo, gamma = optimal_gamma(pb)
    K = _sb10ad(pb, (1.0 + margin) * gamma, job=4)[1]
    # The controller acts on y and u only, which the state scaling leaves unchanged.
    A, B, C, D = plant.close_loop(*K)
    stable = bool(np.all(np.linalg.eigvals(A).real < 0.0))
    cl = balanced(GeneralizedPlant(A=A, B=B, C=C, D=D, n_w=plant.n_w, n_u=0, n_e=plant.n_e,
                                   n_y=0, state_names=(), input_names=(), output_names=(),
                                   t_s=plant.t_s, rho_mps=plant.rho_mps, weights=None))
    gamma_norm = float(control.norm(control.ss(cl.A, cl.B, cl.C, cl.D), "inf")) if stable \
        else math.inf
    gamma_sweep, peak = hinf_norm_sweep(cl.A, cl.B, cl.C, cl.D)
    return FrozenPointResult(t_s=plant.t_s, rho_mps=plant.rho_mps, gamma=gamma,
                             gamma_refused=lo, gamma_check=gamma_norm,
                             gamma_sweep=gamma_sweep, peak_radps=peak, stable=stable)


def lti_study(weights: WeightSet = THESIS, times_s=GRID_TIMES_S,
              context: ModelContext | None = None) -> list[FrozenPointResult]:
    """:func:`frozen_point_gamma` at every grid time for one weight set."""
    return [frozen_point_gamma(weighted_plant(t, weights, context)) for t in times_s]


def _row(label: str, results: list[FrozenPointResult]) -> str:
    cells = [f"{r.gamma:.3f}" for r in results]
    worst = max(r.gamma for r in results)
    return f"| {label} | " + " | ".join(cells) + f" | **{worst:.3f}** |"


def study_variants() -> dict[str, dict[str, WeightSet]]:
    """The weight sets of the study, by table: the two named sets, single relaxations of
    :data:`THESIS`, and each change of :data:`SHIPPED` alone and left out."""
    changes = SHIPPED.changes_from(THESIS)
    return {
        "named sets": {"thesis": THESIS, "shipped": SHIPPED},
        "single relaxations of thesis": {
            k: THESIS.with_changes(k, k, **v) for k, v in SINGLE_RELAXATIONS.items()},
        "changes of shipped, alone on thesis": {
            f"thesis + {k} = {new!r}": THESIS.with_changes(k, k, **{k: new})
            for k, (_, new) in changes.items()},
        "shipped without one change": {
            f"shipped, {k} = {old!r}": SHIPPED.with_changes(k, k, **{k: old})
            for k, (old, _) in changes.items()},
    }


def main(argv=None) -> None:
    """Print the frozen-point γ tables (markdown) of docs/SYNTHESIS_WEIGHTS.md §5."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--details", action="store_true",
                        help="also print the checks of every point")
    args = parser.parse_args(argv)
    for title, sets in study_variants().items():
        print(f"\n{title}\n")
        print("| weights | " + " | ".join(f"{t:g} s" for t in GRID_TIMES_S) + " | max |")
        print("|---" * (len(GRID_TIMES_S) + 2) + "|")
        for label, weights in sets.items():
            results = lti_study(weights)
            print(_row(label, results), flush=True)
            if args.details:
                for r in results:
                    print(f"|   t={r.t_s:g} v={r.rho_mps:.1f}: γ {r.gamma:.4f} (refused "
                          f"{r.gamma_refused:.4f}), check {r.gamma_check:.4f}, sweep "
                          f"{r.gamma_sweep:.4f} at {r.peak_radps:.3g} rad/s, stable "
                          f"{r.stable} |")


if __name__ == "__main__":
    main()
