"""On the REAL weighted plant M(t) at every grid point, the single-point LMI (constant basis,
cvxpy + Clarabel) reproduces slycot sb10ad's optimal γ within 1 %, and its reconstructed
controller closes a stable loop whose weighted H∞ norm (SLICOT ab13dd, independent of the
solver) is within 1 % of that γ.
"""

import numpy as np
import pytest

from vega_lpv.certificate import closed_loop, hinf_norm
from vega_lpv.frozen_point import frozen_point_gamma
from vega_lpv.gridded_plant import GriddedPlant
from vega_lpv.interconnection import GRID_TIMES_S, weighted_plant
from vega_lpv.lpv_synthesis import synthesize
from vega_lpv.weights import WEIGHT_SETS
from vega_model.parameters import default_context


@pytest.mark.slow
@pytest.mark.parametrize("t", GRID_TIMES_S)
def test_single_point_lmi_matches_sb10ad(t):
    m = weighted_plant(t, WEIGHT_SETS["shipped"], default_context())
    sizes = (m.n_w, m.n_u, m.n_e, m.n_y)
    riccati = frozen_point_gamma(m).gamma
    plant = GriddedPlant(np.array([m.rho_mps]), m.A[None], m.B[None], m.C[None], m.D[None],
                         *sizes)
    result = synthesize(plant, rate_bounds=None, basis="constant", backoff=1.0)
    assert result.gamma_min == pytest.approx(riccati, rel=0.01)
    K = result.controller(m.rho_mps, 0.0, plant_point=(m.A, m.B, m.C, m.D))
    A, B, C, D = closed_loop(m.as_point(), K)
    assert np.max(np.linalg.eigvals(A).real) < 0.0
    assert hinf_norm(A, B, C, D) <= 1.01 * result.gamma_min
