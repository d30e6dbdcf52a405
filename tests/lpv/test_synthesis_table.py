"""The committed LPV controller table (``vega synth`` output), checked independently of the
synthesis that produced it: its metadata, its recorded γ against fresh frozen-point closed
loops of the weighted interconnection, and the thesis scenario against Table 3.1.

The synthesis itself does not run here (minutes of cvxpy/Clarabel); these checks rebuild the
plant from the model, close it with the table's interpolated controller and compute
eigenvalues and H∞ norms (SLICOT ab13dd), which takes seconds.
"""

import json
import math

import numpy as np
import pytest

from vega_lpv.certificate import closed_loop, hinf_norm
from vega_lpv.interconnection import GRID_TIMES_S, weighted_plant
from vega_lpv.pipeline import DEFAULT_TABLE, rate_bounds_from_trajectory
from vega_lpv.weights import WEIGHT_SETS
from vega_gnc.controller_table import load_controller_table
from vega_model.dynamics import OUTPUTS
from vega_model.parameters import default_context
from vega_sim.scenario import load_scenario
from vega_sim.closed_loop import run_scenario


@pytest.fixture(scope="module")
def table():
    return load_controller_table(DEFAULT_TABLE)


@pytest.fixture(scope="module")
def context():
    return default_context()


def test_metadata_keys_of_issue_3(table):
    meta = table.metadata
    for key in ("input_names", "measurement_sign", "output_name", "interpolation", "units",
                "weights", "solver", "versions", "git_revision", "created_utc",
                "discretisation", "weight_set", "grid_times_s"):
        assert key in meta, key
    assert set(meta["input_names"]) <= set(OUTPUTS)
    assert meta["measurement_sign"] == -1 and meta["output_name"] == "beta_cmd_rad"
    assert meta["interpolation"] == "linear_in_velocity"
    assert meta["discretisation"]["method"] == "tustin"
    assert table.dt_s == pytest.approx(0.02)
    assert meta["weights"]["name"] == meta["weight_set"] in WEIGHT_SETS
    json.dumps(meta)                                       # plain JSON all the way down


def test_recorded_gammas_and_rate_box(table, context):
    assert 0.0 < table.gamma_min <= table.gamma <= 1.0
    assert table.gamma == pytest.approx(1.2 * table.gamma_min, rel=1e-9)
    lo, hi = rate_bounds_from_trajectory(context)
    # the synthesis' rate box contains the thesis-style bounds of the trajectory
    assert table.rate_grid_mps2[0] <= lo and table.rate_grid_mps2[1] >= hi
    grid_times = table.metadata["grid_times_s"]
    assert set(GRID_TIMES_S) <= {round(t, 6) for t in grid_times}   # the thesis' points
    np.testing.assert_allclose(table.grid_v_mps,
                               [context.parameters(t).v_mps for t in grid_times], rtol=1e-6)
    # γ ordering (docs/LPV_SYNTHESIS.md §5): each frozen-point LTI optimum is a lower bound of the
    # rate-bounded level (the box contains ρ̇ = 0), which is no worse than the quadratic one
    assert max(table.metadata["gamma_lti"]) <= table.gamma_min * (1.0 + 1e-6)
    assert table.gamma_min <= table.metadata["gamma_quadratic"]
    # the synthesis' own record: certificate on the 4× denser grid held everywhere
    dense = table.metadata["dense_certificate"]
    assert dense["factor"] == 4 and dense["n_failed"] == 0 and dense["n_points"] > 4 * 9


@pytest.mark.parametrize("t_s", (10.0, 37.0, 64.0, 90.0))
def test_frozen_closed_loops_meet_the_recorded_gamma(table, context, t_s):
    """At the grid times the ρ̇ = 0 slice is certified (‖·‖∞ ≤ γ); between them the table's
    linear interpolation in v must still stabilise the weighted plant with a norm close to γ.
    """
    weights = WEIGHT_SETS[table.metadata["weight_set"]]
    point = weighted_plant(t_s, weights, context).as_point()
    v = context.parameters(t_s).v_mps
    for rate in table.rate_grid_mps2:
        K = table.interpolate(v, rate, discrete=False)
        A, B, C, D = closed_loop(point, K)
        assert np.max(np.linalg.eigvals(A).real) < 0.0
        norm = hinf_norm(A, B, C, D)
        if t_s in GRID_TIMES_S and rate == 0.0:          # a grid point of every grid kind
            assert norm <= table.gamma * (1.0 + 1e-6)
        assert norm <= 1.0


def test_recorded_controller_stability_is_true(table):
    """An LPV controller may itself be (slowly) unstable at some points; the table records
    its discrete spectral radius per grid point and slice, and the record must be right."""
    radius = np.abs(np.linalg.eigvals(table.Ad)).max(axis=-1)
    np.testing.assert_allclose(radius, table.metadata["spectral_radius"], rtol=1e-9)
    assert (radius < 1.0).tolist() == table.metadata["controller_stable"]
    assert np.all(radius < 1.01)                     # nothing faster than the 50 Hz loop can hold


@pytest.mark.slow
@pytest.mark.parametrize("plant", ("linear", "nonlinear"))
def test_thesis_scenario_meets_table_3_1(table, plant):
    """The thesis' scenario (θ0 = 2°, Dryden wind, seeded INS noise, 10–90 s) through the
    flight software's own controller runtime meets every requirement of Table 3.1."""
    from dataclasses import replace

    scenario = replace(load_scenario("thesis"), plant=plant)
    report = run_scenario(scenario, table).metrics()
    assert report.passed, report.table()
    assert math.isfinite(report["q_alpha"].value)
