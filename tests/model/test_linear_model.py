"""Behaviour of the linear model G_LV(t) against hand-derived physics (docs/MODEL.md)."""

import math

import numpy as np
import pytest

from vega_model.dynamics import INPUTS, OUTPUTS, STATES, linear_model
from vega_model.parameters import model_parameters


def test_names_and_shapes():
    A, B, C, D = linear_model(model_parameters(40.0))
    assert STATES == ("theta_rad", "theta_dot_radps", "z_m", "z_dot_mps",
                      "q1", "q2", "q1_dot", "q2_dot")
    assert INPUTS == ("beta_rad", "beta_ddot_radps2", "wind_mps")
    assert OUTPUTS[0] == "q_alpha_pa_rad" and len(OUTPUTS) == 5
    assert A.shape == (8, 8) and B.shape == (8, 3) and C.shape == (5, 8) and D.shape == (5, 3)


@pytest.mark.parametrize("t", (20.0, 47.0, 70.0))
def test_sign_conventions(t):
    """β > 0 pitches the nose toward +z (θ̈ < 0) and pushes toward −z; wind > 0 lowers α."""
    _, B, C, D = linear_model(model_parameters(t))
    assert B[1, 0] < 0 and B[3, 0] < 0          # TVC moment and lateral force
    assert D[0, 2] < 0                          # v_w > 0 decreases Qα
    assert C[0, 0] > 0 and C[0, 3] > 0          # θ > 0 and ż > 0 increase α
    assert B[1, 2] < 0                          # wind > 0: nose-down aero moment (CP ahead)


def test_rigid_body_divergences_match_hand_values():
    """At max-Q the rigid body has two real divergences (docs/MODEL.md §3):

    * aerodynamic: s ≈ sqrt(μ), μ = N_α (x_CP − x_CG)/J (CP ahead of the CG);
    * drift: s ≈ (T − D_a)/(m V) — the thrust tilted with the attitude bends the path
      (the root left when the large pair ±sqrt(μ) is factored out of the cubic in θ, θ̇, ż).
    """
    p = model_parameters(47.0)
    A, _, _, _ = linear_model(p)
    mu = p.q_pa * p.s_ref_m2 * p.cn_alpha_per_rad * (p.x_cp_m - p.x_cg_m) / p.jyy_kgm2
    assert mu > 0, "the CP must be ahead of the CG (aerodynamically unstable launcher)"
    eig = np.linalg.eigvals(A[:4, :4])
    unstable = np.sort(eig[eig.real > 1e-6].real)
    assert len(unstable) == 2 and np.all(np.abs(eig[eig.real > 1e-6].imag) < 1e-12)
    assert unstable[1] == pytest.approx(math.sqrt(mu), rel=0.05)
    drift = (p.thrust_n - p.axial_force_n) / (p.mass_kg * p.v_mps)
    assert unstable[0] == pytest.approx(drift, rel=0.05)


def test_lift_off_is_regular():
    """At V = 0 the aerodynamic terms vanish instead of dividing by zero."""
    p = model_parameters(0.0)
    assert p.v_mps == 0.0
    A, B, C, D = linear_model(p)
    assert np.all(np.isfinite(A)) and np.all(np.isfinite(C))
    assert A[1, 1] == 0.0 and A[3, 3] == 0.0 and D[0, 2] == 0.0


@pytest.mark.parametrize("t", (0.0, 35.0, 100.0))
def test_bending_poles(t):
    """The bending block has poles −ζω ± jω√(1−ζ²) at the thesis' frequencies (Hz, linear in t)."""
    p = model_parameters(t)
    A, _, _, _ = linear_model(p)
    f1 = 4.71 + (5.89 - 4.71) * min(t, 100.0) / 100.0
    f2 = 10.66 + (13.46 - 10.66) * min(t, 100.0) / 100.0
    eig = np.linalg.eigvals(A)
    for f in (f1, f2):
        w = 2 * math.pi * f
        target = complex(-0.008 * w, w * math.sqrt(1 - 0.008 ** 2))
        assert np.min(np.abs(eig - target)) < 1e-9 * w


def test_ins_lever_arm_and_bending_contamination():
    """z_INS = z − (x_INS − x_CG) θ; θ_INS sees −Ψr^INS q (Eqs. 2.33, 2.35)."""
    p = model_parameters(30.0)
    _, _, C, _ = linear_model(p)
    x = np.zeros(8)
    x[0] = 0.01
    assert (C @ x)[3] == pytest.approx(-(22.9 - p.x_cg_m) * 0.01, rel=1e-12)
    x = np.zeros(8)
    x[4] = 1.0
    assert (C @ x)[1] == pytest.approx(-p.psi_r_ins[0], rel=1e-12)
    assert (C @ x)[3] == pytest.approx(p.psi_t_ins[0], rel=1e-12)


def test_drift_row_has_thrust_tilt():
    """z̈/θ includes −(T − D_a)/m: a pitched vehicle's thrust pushes it sideways."""
    p = model_parameters(47.0)
    A, _, _, _ = linear_model(p)
    aero = p.q_pa * p.s_ref_m2 * p.cn_alpha_per_rad / p.mass_kg
    tilt = (p.thrust_n - p.axial_force_n) / p.mass_kg
    assert tilt > 15.0  # m/s² per rad: thrust dominates the drift coupling
    assert A[3, 0] == pytest.approx(-(tilt + aero), rel=1e-12)


def test_tail_wags_dog_zero():
    """θ/β has a zero pair at ±j sqrt(T l_c / (J_N + m_N l_N l_c)) from the TWD term (§2.7)."""
    p = model_parameters(60.0)
    _, B, _, _ = linear_model(p)
    lc = p.x_cg_m - p.x_pvp_m
    w_twd = math.sqrt(p.thrust_n * lc / (1263.4 + 1616.0 * 0.30 * lc))
    # θ̈ driven by β(s) with β̈ = s²β vanishes where B[1,0] + B[1,1] s² = 0
    assert math.sqrt(B[1, 0] / B[1, 1]) == pytest.approx(w_twd, rel=1e-12)
    assert 30.0 < w_twd < 120.0  # rad/s: above the rigid-body loop, near the bending modes


def test_uncertainty_deviation_scales_entries():
    p = model_parameters(47.0)
    q = p.perturbed({"thrust": 0.1, "jyy": -0.02})
    _, Bp, _, _ = linear_model(p)
    _, Bq, _, _ = linear_model(q)
    assert Bq[1, 0] == pytest.approx(Bp[1, 0] * 1.1 / 0.98, rel=1e-12)
    assert Bq[3, 0] == pytest.approx(Bp[3, 0] * 1.1, rel=1e-12)
