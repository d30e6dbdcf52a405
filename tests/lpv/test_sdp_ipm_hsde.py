"""sdp_ipm.solve_conic_hsde (the self-dual embedding) on SDPs with known answers, its
infeasibility and unboundedness certificates, agreement with Clarabel, and the synthesis'
stage 2 on it (docs/SYNTHESIS.md §8)."""

import cvxpy as cp
import numpy as np
import pytest

from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.lpv_synthesis import IPM, synthesize
from vega_lpv.pipeline import SOLVER_PATHS, run_synthesis
from vega_lpv.sdp_ipm import solve_conic, solve_conic_hsde
from vega_core.errors import BadArgument

from test_lmi_lpv import RATES, RHO, plant_at


def _solve(problem, **options):
    """Solve a cvxpy problem with solve_conic_hsde on its Clarabel canonicalisation."""
    data, chain, inverse = problem.get_problem_data(cp.CLARABEL)
    dims = data["dims"]
    assert not dims.zero and not dims.soc
    answer = solve_conic_hsde(data["A"], data["b"], data["c"], dims.psd, dims.nonneg, **options)
    inverse[-1].solver_options = {}
    problem.unpack_results(answer, chain, inverse)
    return answer


def test_largest_eigenvalue():
    """min t s.t. tI ⪰ C: the optimum is λ_max(C)."""
    rng = np.random.default_rng(7)
    B = rng.standard_normal((6, 6))
    C = B + B.T
    t = cp.Variable()
    problem = cp.Problem(cp.Minimize(t), [t * np.eye(6) - C >> 0])
    answer = _solve(problem, tol_gap_rel=1e-8, tol_gap_abs=1e-9, tol_feas=1e-9)
    assert answer.status == "Solved"
    assert t.value == pytest.approx(np.linalg.eigvalsh(C)[-1], abs=1e-7)


def test_lovasz_theta_of_the_pentagon():
    """θ(C5) = √5 (Lovász 1979): min t s.t. tI − J − Σ_{ij ∈ E} y_ij (E_ij + E_ji) ⪰ 0."""
    n = 5
    edges = [(i, (i + 1) % n) for i in range(n)]
    y, t = cp.Variable(len(edges)), cp.Variable()
    E = []
    for i, j in edges:
        M = np.zeros((n, n))
        M[i, j] = M[j, i] = 1.0
        E.append(M)
    lmi = t * np.eye(n) - np.ones((n, n)) - sum(y[k] * E[k] for k in range(len(edges)))
    problem = cp.Problem(cp.Minimize(t), [lmi >> 0])
    _solve(problem, tol_gap_rel=1e-9, tol_gap_abs=1e-10, tol_feas=1e-10)
    assert t.value == pytest.approx(np.sqrt(5.0), abs=1e-7)


def test_linear_program_with_a_known_vertex():
    """min −x1 − 2 x2 s.t. x1 + x2 ≤ 4, x1 + 3 x2 ≤ 6, x ≥ 0: optimum −5 at (3, 1)."""
    x = cp.Variable(2)
    problem = cp.Problem(cp.Minimize(-x[0] - 2 * x[1]),
                         [x[0] + x[1] <= 4, x[0] + 3 * x[1] <= 6, x >= 0])
    answer = _solve(problem, tol_gap_rel=1e-8, tol_gap_abs=1e-9, tol_feas=1e-9)
    assert answer.status == "Solved"
    assert problem.value == pytest.approx(-5.0, abs=1e-7)
    assert x.value == pytest.approx([3.0, 1.0], abs=1e-6)


def test_primal_infeasibility_is_certified():
    """[[x, 1], [1, −x]] ⪰ 0 has no solution (its determinant is −x² − 1)."""
    x = cp.Variable()
    problem = cp.Problem(cp.Minimize(x), [cp.bmat([[x, 1.0], [1.0, -x]]) >> 0])
    answer = _solve(problem)
    assert answer.status == "PrimalInfeasible"
    assert problem.status == cp.INFEASIBLE
    # the certificate: z ∈ K with Aᵀz = 0 and bᵀz = −1
    data, _, _ = problem.get_problem_data(cp.CLARABEL)
    assert float(data["b"] @ answer.z) == pytest.approx(-1.0)
    assert np.linalg.norm(data["A"].T @ answer.z) < 1e-6


def test_unboundedness_is_certified():
    """min x1 − x2 s.t. [[x2, 1], [1, 1]] ⪰ 0, x1 ≤ 3: x1 is unbounded below (dual infeasible)."""
    x = cp.Variable(2)
    problem = cp.Problem(cp.Minimize(x[0] - x[1]),
                         [cp.bmat([[x[1], 1.0], [1.0, 1.0]]) >> 0, x[0] <= 3.0])
    answer = _solve(problem)
    assert answer.status == "DualInfeasible"
    assert problem.status == cp.UNBOUNDED


@pytest.mark.slow
def test_agrees_with_clarabel_on_a_small_lmi_problem():
    """The bounded-real LMI of a stable 4-state system (its H∞ norm): min γ² s.t.
    [[AᵀP + PA + CᵀC, PB], [BᵀP, −γ²I]] ⪯ 0, P ⪰ 0, against Clarabel."""
    rng = np.random.default_rng(11)
    A = rng.standard_normal((4, 4))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(4)
    B, C = rng.standard_normal((4, 2)), rng.standard_normal((2, 4))
    P, g2 = cp.Variable((4, 4), symmetric=True), cp.Variable()
    lmi = cp.bmat([[A.T @ P + P @ A + C.T @ C, P @ B], [B.T @ P, -g2 * np.eye(2)]])
    problem = cp.Problem(cp.Minimize(g2), [lmi << 0, P >> 0])
    problem.solve(solver="CLARABEL")
    reference = problem.value
    _solve(problem, tol_gap_rel=1e-8, tol_gap_abs=1e-9, tol_feas=1e-9)
    assert problem.value == pytest.approx(reference, rel=1e-5)
    # and both are the H∞ norm² on a frequency grid (from below: a grid misses the peak a bit)
    w = np.logspace(-2, 3, 4000)
    peak = max(np.linalg.norm(C @ np.linalg.solve(1j * wi * np.eye(4) - A, B), 2) for wi in w)
    assert problem.value == pytest.approx(peak ** 2, rel=1e-3)


@pytest.mark.slow
def test_synthesis_stage2_on_the_embedding():
    """The IPM path solves both stages of the small LPV problem (test_lmi_lpv.py); γ_min as
    the Clarabel path within 0.5 %, both certificates negative."""
    plant = GriddedPlant.from_points(RHO, [plant_at(r) for r in RHO])
    old = synthesize(plant, rate_bounds=RATES, solver="CLARABEL", fallback="SCS",
                     stage1_form="full")
    new = synthesize(plant, rate_bounds=RATES, solver=IPM, fallback=("CLARABEL", "SCS"),
                     stage1_form="reduced")
    assert new.solvers == {"stage1": IPM, "stage2": IPM}
    assert new.gamma_min == pytest.approx(old.gamma_min, rel=5e-3)
    assert new.gamma == pytest.approx(1.2 * new.gamma_min)
    assert new.certificate_max_eig < 0.0 and old.certificate_max_eig < 0.0


@pytest.mark.slow
def test_stage1_on_clarabel_stage2_on_the_ipm():
    """The "hybrid" path of `vega synth` (pipeline.SOLVER_PATHS): stage 1 by Clarabel on the
    Schur-reduced LMIs, stage 2 by the IPM; same γ_min as Clarabel alone on the same form."""
    plant = GriddedPlant.from_points(RHO, [plant_at(r) for r in RHO])
    hybrid = synthesize(plant, rate_bounds=RATES, **SOLVER_PATHS["hybrid"])
    assert hybrid.solvers == {"stage1": "CLARABEL", "stage2": IPM}
    alone = synthesize(plant, rate_bounds=RATES, backoff=1.0, solver="CLARABEL", fallback=None,
                       stage1_form="reduced")
    assert hybrid.gamma_min == alone.gamma_min
    assert hybrid.certificate_max_eig < 0.0


def test_unknown_solver_path_is_refused_before_anything_runs():
    with pytest.raises(BadArgument, match="solver path 'fast'"):
        run_synthesis(solver_path="fast", progress=lambda line: None)


def test_centring_floor_of_the_infeasible_start_keeps_the_optimum():
    """solve_conic(centring_floor=0.3) (used for stage 1 since it closed the 26-point gap) on the
    largest-eigenvalue SDP: the same optimum λ_max(C)."""
    rng = np.random.default_rng(5)
    B = rng.standard_normal((8, 8))
    C = B + B.T
    t = cp.Variable()
    problem = cp.Problem(cp.Minimize(t), [t * np.eye(8) - C >> 0, t <= 100.0])
    data, chain, inverse = problem.get_problem_data(cp.CLARABEL)
    dims = data["dims"]
    answer = solve_conic(data["A"], data["b"], data["c"], dims.psd, dims.nonneg,
                         centring_floor=0.3, tol_gap_rel=1e-8, tol_gap_abs=1e-9, tol_feas=1e-9)
    assert answer.status in ("Solved", "AlmostSolved")
    assert answer.obj_val == pytest.approx(np.linalg.eigvalsh(C)[-1], abs=1e-6)
