"""The nonlinear plant equations (vega_model.dynamics) away from the operating point.

The Jacobian test (tests/model/test_model_jacobian.py) sees only first-order terms at the
all-zero operating point. These cases use large angles, where each term of the force and
moment equations (docs/MODEL.md §2) reduces to a closed form worked out by hand here:

* on the pad (t = 0.5 s: thrust 2.02 MN, V = 0, no airflow) thrust alone:
  z̈ = −T sin(θ + β)/m, θ̈ = −l_c T sin β/J, q̈_i = −T Ψt_i sin β;
* bending: the thrust line turned by −ΣΨr q and moved by ΣΨt q;
* the nozzle reaction: centripetal β̇² and tangential β̈ terms at the nozzle CG;
* at max-Q (t = 47 s) a pure angle of attack from ż or θ: α, airspeed and C_N(α) of
  Jorgensen's formula with the vehicle.yaml numbers typed in (C_Nα 2.007 /rad,
  k = 0.68·1.2·75/7.14);
* the INS outputs at large angles, a free bending mode through RK4, one model followed
  across the Mach table segments, and a C_Nα table that varies with Mach.
"""

import math

import numpy as np
import pytest

from vega_model.dynamics import (NonlinearModel, alpha_and_q_alpha, angle_of_attack,
                                 ins_outputs, nonlinear_derivatives, nonlinear_outputs)
from vega_model.parameters import model_parameters

CN_ALPHA = 2.007                        # vehicle.yaml aerodynamics.normal (flat in Mach)
K_CF = 0.68 * 1.2 * 75.0 / 7.14         # vehicle.yaml aerodynamics.crossflow


@pytest.fixture(scope="module")
def pad():
    p = model_parameters(0.5)
    assert p.v_mps == 0.0 and p.thrust_n > 1e6
    return p


@pytest.fixture(scope="module")
def maxq():
    return model_parameters(47.0)


def _x(**kw):
    names = ("theta", "theta_dot", "z", "z_dot", "q1", "q2", "q1_dot", "q2_dot")
    return np.array([float(kw.get(n, 0.0)) for n in names])


def test_thrust_alone_on_the_pad(pad):
    p = pad
    T, m, J, lc = p.thrust_n, p.mass_kg, p.jyy_kgm2, p.l_cg_pvp_m
    theta, beta = 0.3, 0.1
    xd = nonlinear_derivatives(p, _x(theta=theta, theta_dot=0.0, z_dot=0.0), [beta, 0.0, 0.0])
    assert xd[1] == pytest.approx(-lc * T * math.sin(beta) / J, rel=1e-12, abs=0)
    assert xd[3] == pytest.approx(-T * math.sin(theta + beta) / m, rel=1e-12, abs=0)
    for i in (0, 1):
        assert xd[6 + i] == pytest.approx(-T * p.psi_t_pvp[i] * math.sin(beta), rel=1e-12, abs=0)
    assert xd[0] == 0.0 and xd[2] == 0.0 and xd[4] == 0.0 and xd[5] == 0.0


def test_bent_vehicle_on_the_pad(pad):
    """β = 0, q = (0.05, −0.03): the thrust acts along β' = −ΣΨr q at the offset ΣΨt q."""
    p = pad
    T, m, J, lc = p.thrust_n, p.mass_kg, p.jyy_kgm2, p.l_cg_pvp_m
    q1, q2, q1d, q2d = 0.05, -0.03, 0.4, -0.2
    be = -(p.psi_r_pvp[0] * q1 + p.psi_r_pvp[1] * q2)
    off = p.psi_t_pvp[0] * q1 + p.psi_t_pvp[1] * q2
    xd = nonlinear_derivatives(p, _x(q1=q1, q2=q2, q1_dot=q1d, q2_dot=q2d), [0.0, 0.0, 0.0])
    assert xd[1] == pytest.approx((T * math.cos(be) * off - lc * T * math.sin(be)) / J,
                                  rel=1e-12, abs=0)
    assert xd[3] == pytest.approx(-T * math.sin(be) / m, rel=1e-12, abs=0)
    w1, w2 = p.omega_radps
    assert xd[6] == pytest.approx(-w1 * w1 * q1 - 2.0 * p.zeta * w1 * q1d, rel=1e-12, abs=0)
    assert xd[7] == pytest.approx(-w2 * w2 * q2 - 2.0 * p.zeta * w2 * q2d, rel=1e-12, abs=0)
    assert xd[4] == q1d and xd[5] == q2d


def test_nozzle_reaction_on_the_pad(pad):
    """β = 0.2, β̈ = 30, β̇ = 2 at θ = 0.25: the nozzle CG (l_N behind the pivot, mass m_N)
    pushes back with −m_N l_N (β̈ sin β + β̇² cos β) along x and −m_N l_N (β̈ cos β − β̇² sin β)
    along z; its inertia adds −J_N β̈ to the moment."""
    p = pad
    T, m, J, lc = p.thrust_n, p.mass_kg, p.jyy_kgm2, p.l_cg_pvp_m
    mn, ln, jn = p.nozzle_mass_kg, p.nozzle_lever_m, p.nozzle_inertia_kgm2
    theta, beta, bdd, bd = 0.25, 0.2, 30.0, 2.0
    fnx = -mn * ln * (bdd * math.sin(beta) + bd * bd * math.cos(beta))
    fnz = -mn * ln * (bdd * math.cos(beta) - bd * bd * math.sin(beta))
    fx = T * math.cos(beta) + fnx
    fz = -T * math.sin(beta) + fnz
    xd = nonlinear_derivatives(p, _x(theta=theta), [beta, bdd, 0.0, bd])
    assert xd[1] == pytest.approx((-lc * T * math.sin(beta) - jn * bdd + lc * fnz) / J,
                                  rel=1e-12, abs=0)
    assert xd[3] == pytest.approx((-fx * math.sin(theta) + fz * math.cos(theta)) / m,
                                  rel=1e-12, abs=0)
    for i in (0, 1):
        want = p.psi_t_pvp[i] * (-T * math.sin(beta) + fnz) + jn * p.psi_r_pvp[i] * bdd
        assert xd[6 + i] == pytest.approx(want, rel=1e-12, abs=0)
    # three inputs: β̇ = 0
    xd3 = nonlinear_derivatives(p, _x(theta=theta), [beta, bdd, 0.0])
    fnx0 = -mn * ln * bdd * math.sin(beta)
    fnz0 = -mn * ln * bdd * math.cos(beta)
    assert xd3[3] == pytest.approx(((-(T * math.cos(beta) + fnx0)) * math.sin(theta)
                                    + (-T * math.sin(beta) + fnz0) * math.cos(theta)) / m,
                                   rel=1e-12, abs=0)


def _normal(p, airspeed, alpha):
    qbar_s = 0.5 * p.rho_kgpm3 * airspeed ** 2 * p.s_ref_m2
    s = math.sin(alpha)
    return qbar_s * (CN_ALPHA * s * math.cos(alpha) + K_CF * s * abs(s))


@pytest.mark.parametrize("alpha_deg", (10.0, -25.0))
def test_angle_of_attack_from_drift_rate_at_max_q(maxq, alpha_deg):
    """θ = θ̇ = 0, ż = V tan α: α at the CP, airspeed V/cos α; θ̈ = d·N/J, z̈ = −N/m."""
    p = maxq
    a = math.radians(alpha_deg)
    zd = p.v_mps * math.tan(a)
    x = _x(z_dot=zd)
    airspeed = p.v_mps / math.cos(a)
    assert angle_of_attack(p, x, 0.0) == pytest.approx(a, rel=1e-12, abs=0)
    alpha, qa = alpha_and_q_alpha(p, x, 0.0)
    assert alpha == pytest.approx(a, rel=1e-12, abs=0)
    assert qa == pytest.approx(0.5 * p.rho_kgpm3 * airspeed ** 2 * a, rel=1e-12, abs=0)
    assert nonlinear_outputs(p, x, [0.0, 0.0, 0.0])[0] == pytest.approx(qa, rel=1e-12, abs=0)
    n = _normal(p, airspeed, a)
    xd = nonlinear_derivatives(p, x, [0.0, 0.0, 0.0])
    assert xd[1] == pytest.approx(p.l_cp_m * n / p.jyy_kgm2, rel=1e-9, abs=0)
    assert xd[3] == pytest.approx(-n / p.mass_kg, rel=1e-9, abs=0)
    # the same air motion as a wind: v_w = −ż
    assert angle_of_attack(p, _x(), -zd) == pytest.approx(a, rel=1e-12, abs=0)
    np.testing.assert_allclose(nonlinear_derivatives(p, _x(), [0.0, 0.0, -zd])[[1, 3]],
                               xd[[1, 3]], rtol=1e-12)


def test_angle_of_attack_from_attitude_at_max_q(maxq):
    """θ = 8°, ż = 0: the air comes along the reference axis, so α = θ at airspeed V; axial
    force Q S C_A(M) and thrust both tilt with θ: z̈ = (−(T − A) sin θ − N cos θ)/m."""
    p = maxq
    th = math.radians(8.0)
    x = _x(theta=th)
    assert angle_of_attack(p, x, 0.0) == pytest.approx(th, rel=1e-12, abs=0)
    n = _normal(p, p.v_mps, th)
    axial = 0.5 * p.rho_kgpm3 * p.v_mps ** 2 * p.s_ref_m2 * float(p.aero.c_a(p.mach))
    xd = nonlinear_derivatives(p, x, [0.0, 0.0, 0.0])
    T, m = p.thrust_n, p.mass_kg
    assert xd[3] == pytest.approx((-(T - axial) * math.sin(th) - n * math.cos(th)) / m,
                                  rel=1e-9, abs=0)
    assert xd[1] == pytest.approx(p.l_cp_m * n / p.jyy_kgm2, rel=1e-9, abs=0)


def test_pitch_rate_moves_the_air_at_the_cp(maxq):
    """θ = 0, θ̇ = 0.05 rad/s: the CP (d ahead of the CG) moves at −θ̇ d along z:
    α = atan2(−θ̇ d, V), airspeed hypot(V, θ̇ d)."""
    p = maxq
    d = p.l_cp_m
    x = _x(theta_dot=0.05)
    a = math.atan2(-0.05 * d, p.v_mps)
    airspeed = math.hypot(p.v_mps, 0.05 * d)
    alpha, qa = alpha_and_q_alpha(p, x, 0.0)
    assert alpha == pytest.approx(a, rel=1e-12, abs=0)
    assert qa == pytest.approx(0.5 * p.rho_kgpm3 * airspeed ** 2 * a, rel=1e-12, abs=0)
    xd = nonlinear_derivatives(p, x, [0.0, 0.0, 0.0])
    assert xd[3] == pytest.approx(-_normal(p, airspeed, a) / p.mass_kg, rel=1e-9, abs=0)
    assert xd[0] == 0.05


def test_ins_outputs_at_large_angles(maxq):
    """θ_INS = θ − ΣΨr q, θ̇_INS = θ̇ − ΣΨr q̇, z_INS = z − l sin θ + ΣΨt q,
    ż_INS = ż − l cos θ θ̇ + ΣΨt q̇ (thesis Eqs. 2.33–2.36, l = x_INS − x_CG)."""
    p = maxq
    th, thd, z, zd = 0.6, 0.3, 12.0, -4.0
    q = (0.2, -0.1)
    qd = (1.5, 0.7)
    x = np.array([th, thd, z, zd, q[0], q[1], qd[0], qd[1]])
    ri, ti, li = p.psi_r_ins, p.psi_t_ins, p.l_ins_m
    want = [th - ri[0] * q[0] - ri[1] * q[1],
            thd - ri[0] * qd[0] - ri[1] * qd[1],
            z - li * math.sin(th) + ti[0] * q[0] + ti[1] * q[1],
            zd - li * math.cos(th) * thd + ti[0] * qd[0] + ti[1] * qd[1]]
    np.testing.assert_allclose(ins_outputs(p, x), want, rtol=1e-12)
    np.testing.assert_allclose(nonlinear_outputs(p, x, [0.0, 0.0, 0.0])[1:], want, rtol=1e-12)


def test_rk4_step_of_a_free_bending_mode_is_the_damped_oscillator(pad):
    """Before ignition (t = 0: thrust 0, V = 0) a displaced first mode is a free damped
    oscillator q̈ = −ω²q − 2ζωq̇: 1000 RK4 steps of 0.1 ms against the exact solution."""
    p = model_parameters(0.0)            # thrust 0: the mode is a free damped oscillator
    assert p.thrust_n == 0.0
    model = NonlinearModel(p)
    w, z = p.omega_radps[0], p.zeta
    x = (0.0, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0)
    h = 1e-4
    for _ in range(1000):
        x = model.rk4_step(x, (0.0, 0.0, 0.0, 0.0), h)
    t = 0.1
    wd = w * math.sqrt(1.0 - z * z)
    exact = 0.01 * math.exp(-z * w * t) * (math.cos(wd * t) + z * w / wd * math.sin(wd * t))
    assert x[4] == pytest.approx(exact, rel=1e-9, abs=0)
    assert x[5] == 0.0 and x[0] == 0.0 and x[3] == 0.0


def test_model_keeps_its_parameters(maxq):
    assert NonlinearModel(maxq).p is maxq


def _z_ddot_hand(p, cn_alpha_of, x, beta=0.0):
    """z̈ and θ̈ from the force/moment equations with the given C_Nα(M) and the numpy table
    C_A(M) (Aerodynamics.c_a: numpy.interp), β = 0, no bending, no nozzle motion."""
    th, thd, zd = x[0], x[1], x[3]
    d = p.l_cp_m
    vx = p.v_mps - thd * d * math.sin(th)
    vz = zd - thd * d * math.cos(th)
    alpha = math.atan2(vx * math.sin(th) + vz * math.cos(th),
                       vx * math.cos(th) - vz * math.sin(th))
    airspeed = math.hypot(vx, vz)
    mach = airspeed / p.sound_speed_mps
    qbar_s = 0.5 * p.rho_kgpm3 * airspeed ** 2 * p.s_ref_m2
    s = math.sin(alpha)
    normal = qbar_s * (cn_alpha_of(mach) * s * math.cos(alpha) + K_CF * s * abs(s))
    axial = qbar_s * float(p.aero.c_a(mach))
    fx = p.thrust_n - axial
    fz = -normal
    return ((-fx * math.sin(th) + fz * math.cos(th)) / p.mass_kg,
            d * normal / p.jyy_kgm2, mach)


def test_one_model_follows_the_mach_number_across_table_segments():
    """One model (its cached table segments) evaluated at states whose airspeed moves the
    Mach number up through several C_A breakpoints, beyond the C_Nα table (M > 8) and back:
    every evaluation equals the hand equations with numpy's tables."""
    p = model_parameters(20.0)
    model = NonlinearModel(p)
    machs = []
    for zd in (0.0, 150.0, 400.0, 900.0, 2800.0, 3000.0, 600.0, 0.0, -300.0):
        x = _x(theta=0.2, z_dot=zd)
        got = model.derivatives(x, (0.0, 0.0, 0.0))
        zdd, tdd, mach = _z_ddot_hand(p, lambda m: CN_ALPHA, x)
        machs.append(mach)
        assert got[3] == pytest.approx(zdd, rel=1e-9, abs=1e-9)
        assert got[1] == pytest.approx(tdd, rel=1e-9, abs=1e-9)
    assert min(machs) < 1.0 and max(machs) > 8.0


def test_sloped_normal_force_table_is_interpolated(maxq):
    """With a C_Nα table that varies with Mach (1.5 → 2.25 /rad from M 1 to 4; the shipped
    one is flat), the model reads C_Nα at the actual Mach of the airflow."""
    import dataclasses

    from vega_model.aero import Aerodynamics
    from vega_model.vehicle_data import load_vehicle_data

    vd = load_vehicle_data()
    table = {k: vd[k] for k in (
        "geometry.s_ref_m2", "aerodynamics.axial.mach", "aerodynamics.axial.c_a",
        "aerodynamics.normal.x_cp_m", "aerodynamics.crossflow.eta",
        "aerodynamics.crossflow.c_dc", "aerodynamics.crossflow.planform_area_m2")}
    table["aerodynamics.normal.mach"] = np.array([1.0, 4.0])
    table["aerodynamics.normal.cn_alpha_per_rad"] = np.array([1.5, 2.25])
    table["aerodynamics.normal.x_cp_m"] = np.array([18.36, 18.36])
    p = dataclasses.replace(maxq, aero=Aerodynamics(table))
    model = NonlinearModel(p)
    for zd in (30.0, 120.0, -60.0):
        x = _x(theta=0.05, z_dot=zd)
        got = model.derivatives(x, (0.0, 0.0, 0.0))
        zdd, tdd, mach = _z_ddot_hand(p, lambda m: 1.5 + 0.25 * (m - 1.0), x)
        assert 1.0 < mach < 4.0
        assert got[3] == pytest.approx(zdd, rel=1e-9, abs=0)
        assert got[1] == pytest.approx(tdd, rel=1e-9, abs=0)


def test_attitude_pitch_rate_and_drift_rate_together(maxq):
    """θ = 0.3, θ̇ = 0.2 rad/s, ż = 40 m/s (z = 7 m, which must not enter): the CP's air
    velocity (V − θ̇ d sin θ, ż − θ̇ d cos θ) resolved in body axes gives α."""
    p = maxq
    th, thd, zd = 0.3, 0.2, 40.0
    d = p.l_cp_m
    vx = p.v_mps - thd * d * math.sin(th)
    vz = zd - thd * d * math.cos(th)
    a = math.atan2(vx * math.sin(th) + vz * math.cos(th), vx * math.cos(th) - vz * math.sin(th))
    x = _x(theta=th, theta_dot=thd, z=7.0, z_dot=zd)
    assert angle_of_attack(p, x, 0.0) == pytest.approx(a, rel=1e-12, abs=0)
    alpha, qa = alpha_and_q_alpha(p, x, 0.0)
    assert qa == pytest.approx(0.5 * p.rho_kgpm3 * (vx * vx + vz * vz) * a, rel=1e-12, abs=0)
    got = NonlinearModel(p).derivatives(x, (0.0, 0.0, 0.0))
    zdd, tdd, _ = _z_ddot_hand(p, lambda m: CN_ALPHA, x)
    assert got[3] == pytest.approx(zdd, rel=1e-9, abs=0)
    assert got[1] == pytest.approx(tdd, rel=1e-9, abs=0)
