"""Pitch-plane launcher dynamics: the linear model G_LV(t) and its nonlinear counterpart.

One module holds the plant equations (thesis Ch. 2, re-derived from the force and moment
equations of §2.4; derivation and sign conventions in docs/MODEL.md):

* :func:`linear_model` — the frozen-time state-space model of thesis Eq. 2.44:
  states ``[θ, θ̇, z, ż, q1, q2, q̇1, q̇2]``, inputs ``[β, β̈, v_w]``,
  outputs ``[Qα, θ_INS, θ̇_INS, z_INS, ż_INS]``.
* :func:`nonlinear_derivatives` / :func:`nonlinear_outputs` — the same physics without
  small-angle approximations in α, β and θ, with the nonlinear normal-force curve
  C_N(α, M), thrust resolved through the actual angles and the nozzle (tail-wags-dog)
  kinematics; its Jacobian at the operating point of thesis Table 2.2 (all zero) equals
  :func:`linear_model` (tests/test_model_jacobian.py).
* :func:`ins_outputs` — INS-location kinematics, Eqs. 2.33–2.36 (also used by the INS model).

Conventions: x forward along the reference velocity, z normal to it in the pitch plane;
θ > 0 is a right-handed rotation about y (nose toward −z); β > 0 rotates the nozzle in the
same sense (lateral thrust −T·sinβ); v_w > 0 is air moving toward +z; Qα in Pa·rad.
"""

from __future__ import annotations

import math

import numpy as np

from .parameters import ModelParameters

__all__ = [
    "STATES", "INPUTS", "OUTPUTS", "NONLINEAR_INPUTS",
    "linear_model", "nonlinear_derivatives", "nonlinear_outputs", "ins_outputs",
    "angle_of_attack",
]

STATES = ("theta_rad", "theta_dot_radps", "z_m", "z_dot_mps",
          "q1", "q2", "q1_dot", "q2_dot")
INPUTS = ("beta_rad", "beta_ddot_radps2", "wind_mps")
OUTPUTS = ("q_alpha_pa_rad", "theta_ins_rad", "theta_dot_ins_radps",
           "z_ins_m", "z_dot_ins_mps")
# The nonlinear model also takes the nozzle rate (it enters only quadratically, through
# the centripetal acceleration of the nozzle CG, so it has no linear counterpart).
NONLINEAR_INPUTS = INPUTS + ("beta_dot_radps",)


def linear_model(p: ModelParameters) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frozen-time linear model G_LV(t) (thesis Eq. 2.44, re-derived).

    Parameters
    ----------
    p
        Model parameters at the flight time of interest.

    Returns
    -------
    A, B, C, D
        ``A`` 8×8, ``B`` 8×3, ``C`` 5×8, ``D`` 5×3 in the orders :data:`STATES`,
        :data:`INPUTS`, :data:`OUTPUTS`.

    Notes
    -----
    With N_α = Q·S·C_Nα, l_c = x_CG − x_PVP, d = x_CP − x_CG, l = x_INS − x_CG and the
    axial (drag) force D_a, the rows are (docs/MODEL.md §3)::

        θ̈  = N_α d/J (θ − d θ̇/V + ż/V − v_w/V) + T Σ(Ψt_i + l_c Ψr_i) q_i/J
             − T l_c/J β − (J_N + m_N l_N l_c)/J β̈
        z̈  = −(T − D_a)/m θ − N_α/m (θ − d θ̇/V + ż/V − v_w/V) + T Σ Ψr_i q_i/m
             − T/m β − m_N l_N/m β̈
        q̈_i = −ω_i² q_i − 2ζω_i q̇_i − T Ψt_i β + (J_N Ψr_i − m_N l_N Ψt_i) β̈

    (Ψ at the pivot). The thesis' drift row lacks the thrust-tilt term −(T − D_a)/m θ and
    has the opposite sign on its aerodynamic entries; its pitch-damping entry has the
    wrong sign; its C matrix adds rather than subtracts the INS slopes (Eqs. 2.33–2.36
    subtract them). These deviations are derived and listed in docs/MODEL.md.
    """
    T, m, J = p.thrust_n, p.mass_kg, p.jyy_kgm2
    n_a = p.normal_force_slope_n
    # N_α/V and Q/V written without dividing by V, so that lift-off (V = 0) is regular
    n_v = 0.5 * p.rho_kgpm3 * p.v_mps * p.s_ref_m2 * p.cn_alpha_per_rad
    q_v = 0.5 * p.rho_kgpm3 * p.v_mps
    d, lc, li = p.l_cp_m, p.l_cg_pvp_m, p.l_ins_m
    mn, ln, jn = p.nozzle_mass_kg, p.nozzle_lever_m, p.nozzle_inertia_kgm2
    w1, w2 = p.omega_radps
    tp, rp, ti, ri = p.psi_t_pvp, p.psi_r_pvp, p.psi_t_ins, p.psi_r_ins
    # N_α·∂α/∂[θ, θ̇, ż, v_w] with α = θ + (ż − v_w − d θ̇)/V at the CP (thesis Eqs. 2.9-2.10)
    force_alpha = np.array([n_a, -n_v * d, n_v, -n_v])

    A = np.zeros((8, 8))
    B = np.zeros((8, 3))
    A[0, 1] = 1.0
    A[2, 3] = 1.0
    A[4, 6] = 1.0
    A[5, 7] = 1.0
    # pitch: aerodynamic moment N_α d α, thrust through the bent pivot, TVC, TWD
    A[1, [0, 1, 3]] = d / J * force_alpha[:3]
    A[1, 4] = T * (tp[0] + lc * rp[0]) / J
    A[1, 5] = T * (tp[1] + lc * rp[1]) / J
    B[1] = [-T * lc / J, -(jn + mn * ln * lc) / J, d / J * force_alpha[3]]
    # drift: thrust and axial force tilted by θ, normal force, thrust through the bent pivot
    A[3, [0, 1, 3]] = -force_alpha[:3] / m
    A[3, 0] -= (T - p.axial_force_n) / m
    A[3, 4] = T * rp[0] / m
    A[3, 5] = T * rp[1] / m
    B[3] = [-T / m, -mn * ln / m, -force_alpha[3] / m]
    # bending modes (thesis Eqs. 2.27-2.28)
    A[6, 4], A[6, 6] = -w1 * w1, -2.0 * p.zeta * w1
    A[7, 5], A[7, 7] = -w2 * w2, -2.0 * p.zeta * w2
    B[6, :2] = [-T * tp[0], jn * rp[0] - mn * ln * tp[0]]
    B[7, :2] = [-T * tp[1], jn * rp[1] - mn * ln * tp[1]]

    C = np.zeros((5, 8))
    D = np.zeros((5, 3))
    C[0, [0, 1, 3]] = [p.q_pa, -q_v * d, q_v]
    D[0, 2] = -q_v
    # INS (thesis Eqs. 2.33-2.36)
    C[1, 0], C[1, 4], C[1, 5] = 1.0, -ri[0], -ri[1]
    C[2, 1], C[2, 6], C[2, 7] = 1.0, -ri[0], -ri[1]
    C[3, 2], C[3, 0], C[3, 4], C[3, 5] = 1.0, -li, ti[0], ti[1]
    C[4, 3], C[4, 1], C[4, 6], C[4, 7] = 1.0, -li, ti[0], ti[1]
    return A, B, C, D


def _airflow(p: ModelParameters, theta: float, theta_dot: float, z_dot: float,
             wind: float) -> tuple[float, float]:
    """Angle of attack at the CP [rad] and airspeed there [m/s] (thesis Eqs. 2.9-2.10)."""
    d = p.l_cp_m
    s, c = math.sin(theta), math.cos(theta)
    # air-relative velocity of the CP in the reference frame (x along, z normal)
    vx = p.v_mps - theta_dot * d * s
    vz = z_dot - wind - theta_dot * d * c
    # ... resolved in body axes: u along the body axis, w along body z
    u = vx * c - vz * s
    w = vx * s + vz * c
    return math.atan2(w, u), math.hypot(vx, vz)


def angle_of_attack(p: ModelParameters, x, wind_mps: float) -> float:
    """Angle of attack at the CP [rad] for state ``x`` and wind ``wind_mps``."""
    return _airflow(p, float(x[0]), float(x[1]), float(x[3]), float(wind_mps))[0]


def nonlinear_derivatives(p: ModelParameters, x, u) -> np.ndarray:
    """State derivative of the nonlinear pitch-plane perturbation model.

    Parameters
    ----------
    p
        Model parameters at the current flight time (time-varying parameters enter
        through ``p``; the aerodynamic coefficients are re-evaluated at the actual Mach).
    x
        State, order :data:`STATES`.
    u
        Inputs ``[β, β̈, v_w]`` or ``[β, β̈, v_w, β̇]`` (:data:`NONLINEAR_INPUTS`;
        β̇ defaults to 0).

    Notes
    -----
    Forces in body axes (docs/MODEL.md §2): thrust T at the pivot along the nozzle, whose
    angle to the rigid-body axis is β' = β − Σ Ψr_i q_i and whose application point is
    displaced by Σ Ψt_i q_i; normal force N = Q S C_N(α, M) and axial force
    Q S C_A(M) at the CP; the nozzle's reaction force −m_N·a_NozzleCG and moment −J_N β̈
    at the pivot. The drift equation is written along the reference normal: gravity
    acts identically on the vehicle and on the reference point and cancels.
    """
    theta, theta_dot, _z, z_dot, q1, q2, q1d, q2d = (float(v) for v in x)
    beta, beta_dd, wind = float(u[0]), float(u[1]), float(u[2])
    beta_d = float(u[3]) if len(u) > 3 else 0.0
    T, m, J = p.thrust_n, p.mass_kg, p.jyy_kgm2
    lc, d = p.l_cg_pvp_m, p.l_cp_m
    mn, ln, jn = p.nozzle_mass_kg, p.nozzle_lever_m, p.nozzle_inertia_kgm2
    tp, rp = p.psi_t_pvp, p.psi_r_pvp
    w1, w2 = p.omega_radps

    alpha, airspeed = _airflow(p, theta, theta_dot, z_dot, wind)
    mach = airspeed / p.sound_speed_mps
    qbar_s = 0.5 * p.rho_kgpm3 * airspeed * airspeed * p.s_ref_m2
    normal = qbar_s * float(p.aero.cn(alpha, mach))
    axial = qbar_s * float(p.aero.c_a(mach))

    beta_eff = beta - (rp[0] * q1 + rp[1] * q2)
    offset = tp[0] * q1 + tp[1] * q2
    sb, cb = math.sin(beta), math.cos(beta)
    # nozzle reaction at the pivot (nozzle CG l_N behind the pivot, rotated by β)
    fnx = -mn * ln * (beta_dd * sb + beta_d * beta_d * cb)
    fnz = -mn * ln * (beta_dd * cb - beta_d * beta_d * sb)
    fx = T * math.cos(beta_eff) - axial + fnx
    fz = -T * math.sin(beta_eff) - normal + fnz
    moment = (d * normal
              + T * math.cos(beta_eff) * offset - lc * T * math.sin(beta_eff)
              - jn * beta_dd + lc * fnz)
    st, ct = math.sin(theta), math.cos(theta)
    # generalised modal forces (thesis Eq. 2.28 terms, β through the actual angle)
    modal = -T * sb + fnz
    return np.array([
        theta_dot,
        moment / J,
        z_dot,
        (-fx * st + fz * ct) / m,
        q1d,
        q2d,
        -w1 * w1 * q1 - 2.0 * p.zeta * w1 * q1d + tp[0] * modal + jn * rp[0] * beta_dd,
        -w2 * w2 * q2 - 2.0 * p.zeta * w2 * q2d + tp[1] * modal + jn * rp[1] * beta_dd,
    ])


def ins_outputs(p: ModelParameters, x) -> np.ndarray:
    """INS-location pitch, pitch rate, drift and drift rate (thesis Eqs. 2.33-2.36).

    The INS sits l = x_INS − x_CG ahead of the CG; bending adds the local slope
    (subtracted, θ_local = θ − Σ Ψr q) and the local displacement (added).
    """
    theta, theta_dot, z, z_dot, q1, q2, q1d, q2d = (float(v) for v in x)
    ri, ti, li = p.psi_r_ins, p.psi_t_ins, p.l_ins_m
    return np.array([
        theta - ri[0] * q1 - ri[1] * q2,
        theta_dot - ri[0] * q1d - ri[1] * q2d,
        z - li * math.sin(theta) + ti[0] * q1 + ti[1] * q2,
        z_dot - li * math.cos(theta) * theta_dot + ti[0] * q1d + ti[1] * q2d,
    ])


def nonlinear_outputs(p: ModelParameters, x, u) -> np.ndarray:
    """Outputs ``[Qα, θ_INS, θ̇_INS, z_INS, ż_INS]`` of the nonlinear model.

    Qα = Q·α with Q the dynamic pressure of the actual airspeed at the CP and α the
    signed angle of attack there (thesis Eq. 2.18 in the pitch plane) [Pa·rad].
    """
    alpha, airspeed = _airflow(p, float(x[0]), float(x[1]), float(x[3]), float(u[2]))
    q_alpha = 0.5 * p.rho_kgpm3 * airspeed * airspeed * alpha
    return np.concatenate(([q_alpha], ins_outputs(p, x)))
