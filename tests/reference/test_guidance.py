"""The offline guidance reference: dynamics, drift bounds, the INS view and the load it flies,
each checked against formulas written out here (docs/GUIDANCE.md), not the code's own."""

import numpy as np
import pytest

from vega_reference.guidance import DesignWind, GuidanceWeights, design_reference
from vega_gnc.guidance_reference import default_reference_path, load_guidance_reference
from vega_model.parameters import default_context
from vega_model.wind import wind_profile_mps

# every test here shares a module fixture that takes seconds (a solve or a flight)
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def design():
    return design_reference()


@pytest.fixture(scope="module")
def params(design):
    ctx = default_context()
    return [ctx.parameters(float(t)) for t in design.t_s]


def test_starts_on_the_nominal_and_keeps_half_the_drift_budget(design):
    w = GuidanceWeights()
    assert np.array_equal(design.states[0], np.zeros(4))
    assert np.array_equal(design.reference[0], np.zeros(4))
    assert np.abs(design.states[:, 2]).max() <= w.z_max_m + 1e-6
    assert np.abs(design.states[:, 3]).max() <= w.z_dot_max_mps + 1e-6
    assert max(design.summary["dynamics_residual_max"]) < 1e-9
    # the drift bound binds: the load would take more drift if it could
    assert np.abs(design.states[:, 2]).max() > 0.99 * w.z_max_m


def test_reference_is_what_the_ins_measures_on_the_reference_flight(design, params):
    """Rigid INS kinematics (thesis Eqs. 2.33-2.36 with q = 0): θ_INS = θ, θ̇_INS = θ̇,
    z_INS = z − l·θ, ż_INS = ż − l·θ̇ with l = x_INS − x_CG."""
    lever = np.array([p.x_ins_m - p.x_cg_m for p in params])
    th, thd, z, zd = design.states.T
    want = np.column_stack([th, thd, z - lever * th, zd - lever * thd])
    assert np.allclose(design.reference, want, rtol=0, atol=1e-12)


def test_load_of_the_reference_flight_from_the_angle_of_attack(design, params):
    """Qα = Q·α with α = θ + (ż − v_w − d·θ̇)/V at the CP, d = x_CP − x_CG (thesis Eqs. 2.9-2.10),
    v_w = V_w(h_nom) of Eq. 2.54; wherever the vehicle moves (V > 0, from ≈ 0.6 s)."""
    ctx = default_context()
    th, thd, _, zd = design.states.T
    k = np.array([i for i, p in enumerate(params) if p.v_mps > 0.0])
    assert k.size > 990
    v = np.array([params[i].v_mps for i in k])
    q = np.array([params[i].q_pa for i in k])
    d = np.array([params[i].x_cp_m - params[i].x_cg_m for i in k])
    vw = np.array([wind_profile_mps(params[i].h_m, ctx.vehicle) for i in k])
    alpha = th[k] + (zd[k] - vw - d * thd[k]) / v
    assert np.allclose(design.q_alpha_pa_rad[k], q * alpha, rtol=1e-9, atol=1e-6)
    assert np.allclose(design.q_alpha_hold_pa_rad[k], -q * vw / v, rtol=1e-9, atol=1e-6)


def test_the_bias_removes_the_steady_wind_load(design):
    """Holding the nominal attitude in the design wind exceeds the envelope near Mach 0.31
    (≈ 10.8 s); the reference flight stays below 60 % of it everywhere."""
    hold = np.abs(design.q_alpha_hold_pa_rad) / design.envelope_pa_rad
    ratio = np.abs(design.q_alpha_pa_rad) / design.envelope_pa_rad
    assert hold.max() > 1.1 and 10.0 <= design.t_s[hold.argmax()] <= 11.5
    assert ratio.max() < 0.6
    assert design.summary["beta_ff_max_deg"] < 1.0


def test_no_wind_no_bias():
    still = design_reference(DesignWind(scale=0.0))
    assert np.abs(still.states).max() < 1e-9 and np.abs(still.beta_ff_rad).max() < 1e-9


def test_shipped_reference_is_this_design(design):
    """vega_gnc/config/guidance_reference.npz is what `vega guidance` computes today."""
    shipped = load_guidance_reference(default_reference_path())
    assert np.array_equal(shipped.t_s, design.t_s)
    scale = np.abs(design.reference).max(axis=0)
    assert np.allclose(shipped.reference, design.reference, rtol=0, atol=1e-6 * scale.max())
    assert np.allclose(shipped.beta_ff_rad, design.beta_ff_rad, rtol=0, atol=1e-8)
    assert shipped.metadata["design_wind"]["scale"] == 1.0
