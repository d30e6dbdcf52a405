"""The faster solver paths of the synthesis against the ones they replace.

- sdp_ipm.solve_conic (normal-equations interior point) against Clarabel on a small SDP;
- the stage-1 LMIs Schur-reduced with h ≥ g² (``stage1_form="reduced"``) against the 3×3-block
  form (``"full"``), both with Clarabel;
- the IPM path (``solver="IPM"`` on the reduced stage-1 LMIs; pipeline.SOLVER_PATHS "ipm", the
  default of `vega synth`) against the Clarabel full-form path (SOLVER_PATHS "clarabel", the
  one that produced the shipped lpv_controller.npz)
  on the small LPV plant of test_lmi_lpv.py: γ_min within 0.5 %, both certificates negative.
"""

import cvxpy as cp
import numpy as np
import pytest

from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.lpv_synthesis import IPM, synthesize
from vega_lpv.sdp_ipm import solve_conic

from test_lmi_lpv import RATES, RHO, plant_at


@pytest.fixture(scope="module")
def plant():
    return GriddedPlant.from_points(RHO, [plant_at(r) for r in RHO])


def _small_sdp():
    """min λ_max(F0 + Σ x_i F_i) + 0.1 Σ x_i over a box: PSD cones of two sizes, nonneg rows."""
    rng = np.random.default_rng(3)
    F = [(lambda M: M + M.T)(rng.standard_normal((5, 5))) for _ in range(4)]
    G = [(lambda M: M + M.T)(rng.standard_normal((3, 3))) for _ in range(4)]
    x, t = cp.Variable(3), cp.Variable()
    cons = [t * np.eye(5) - (F[0] + sum(x[i] * F[i + 1] for i in range(3))) >> 0,
            np.eye(3) * 4 + G[0] + sum(x[i] * G[i + 1] for i in range(3)) >> 0,
            x >= -1.0, x <= 1.0]
    return cp.Problem(cp.Minimize(t + 0.1 * cp.sum(x)), cons), x, t


@pytest.mark.filterwarnings("ignore:Solution may be inaccurate")
def test_ipm_matches_clarabel_on_a_small_sdp():
    problem, x, t = _small_sdp()
    problem.solve(solver="CLARABEL")
    reference, x_ref = problem.value, x.value.copy()
    data, chain, inverse = problem.get_problem_data(cp.CLARABEL)
    dims = data["dims"]
    answer = solve_conic(data["A"], data["b"], data["c"], dims.psd, dims.nonneg,
                         tol_gap_rel=1e-8, tol_gap_abs=1e-9, tol_feas=1e-9)
    assert answer.status in ("Solved", "AlmostSolved")
    inverse[-1].solver_options = {}
    problem.unpack_results(answer, chain, inverse)
    assert problem.value == pytest.approx(reference, rel=1e-5, abs=1e-6)
    assert np.allclose(x.value, x_ref, atol=1e-3)


def test_ipm_rejects_unsupported_cones():
    with pytest.raises(ValueError, match="zero cones"):
        solve_conic(np.eye(2), np.ones(2), np.ones(2), (), 1, n_zero=1)


@pytest.mark.slow
def test_reduced_stage1_matches_full_form(plant):
    full = synthesize(plant, rate_bounds=RATES, backoff=1.0, solver="CLARABEL", fallback=None,
                      stage1_form="full")
    reduced = synthesize(plant, rate_bounds=RATES, backoff=1.0, solver="CLARABEL",
                         fallback=None, stage1_form="reduced")
    assert reduced.gamma_min == pytest.approx(full.gamma_min, rel=1e-3)
    assert reduced.certificate_max_eig < 0.0


@pytest.mark.slow
def test_ipm_path_matches_the_clarabel_path(plant):
    old = synthesize(plant, rate_bounds=RATES, solver="CLARABEL", fallback="SCS",
                     stage1_form="full")
    new = synthesize(plant, rate_bounds=RATES, solver="IPM", fallback=("CLARABEL", "SCS"),
                     stage1_form="reduced")
    assert new.solvers["stage1"] == IPM
    assert new.gamma_min == pytest.approx(old.gamma_min, rel=5e-3)
    assert new.certificate_max_eig < 0.0 and old.certificate_max_eig < 0.0


def test_stage1_form_is_validated(plant):
    with pytest.raises(ValueError, match="stage1_form"):
        synthesize(plant, rate_bounds=RATES, stage1_form="other")
