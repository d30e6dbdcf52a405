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
  :func:`linear_model` (tests/model/test_model_jacobian.py).
* :func:`ins_outputs` — INS-location kinematics, Eqs. 2.33–2.36 (also used by the INS model).

Conventions: x forward along the reference velocity, z normal to it in the pitch plane;
θ > 0 is a right-handed rotation about y (nose toward −z); β > 0 rotates the nozzle in the
same sense (lateral thrust −T·sinβ); v_w > 0 is air moving toward +z; Qα in Pa·rad.
"""

from __future__ import annotations

import math

import numpy as np

from vega_model.parameters import ModelParameters

__all__ = [
    "STATES", "INPUTS", "OUTPUTS", "NONLINEAR_INPUTS",
    "linear_model", "nonlinear_derivatives", "NonlinearModel", "nonlinear_outputs",
    "ins_outputs", "ins_outputs_tuple", "angle_of_attack", "alpha_and_q_alpha",
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


def alpha_and_q_alpha(p: ModelParameters, x, wind_mps: float) -> tuple[float, float]:
    """Angle of attack at the CP [rad] and Qα [Pa·rad] for state ``x`` and wind ``wind_mps``
    (the first output of :func:`nonlinear_outputs`, as plain floats)."""
    alpha, airspeed = _airflow(p, float(x[0]), float(x[1]), float(x[3]), float(wind_mps))
    return alpha, 0.5 * p.rho_kgpm3 * airspeed * airspeed * alpha


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
    The equations are :class:`NonlinearModel` (one implementation, in plain floats, which the
    plant's RK4 integrator calls directly); this is its derivative as an array.
    """
    return np.array(NonlinearModel(p).derivatives(x, u))


class NonlinearModel:
    """The nonlinear pitch-plane model at one parameter set, in plain float arithmetic.

    Parameters
    ----------
    p
        Model parameters (held for the model's life; build one model per parameter set).

    Notes
    -----
    Forces in body axes (docs/MODEL.md §2): thrust T at the pivot along the nozzle, whose
    angle to the rigid-body axis is β' = β − Σ Ψr_i q_i and whose application point is
    displaced by Σ Ψt_i q_i; normal force N = Q S C_N(α, M) (C_N of
    :meth:`vega_model.aero.Aerodynamics.cn`) and axial force Q S C_A(M) at the CP, Q and M of
    the actual airspeed there; the nozzle's reaction force −m_N·a_NozzleCG and moment −J_N β̈
    at the pivot. The drift equation is written along the reference normal: gravity acts
    identically on the vehicle and on the reference point and cancels.

    Speed without a change of numbers: the parameter products are formed once per parameter
    set and the input-only terms (nozzle reaction, β̈ terms) once per set of held inputs, each
    with the same floating-point operations in the same order as the plain formulas, and the
    Mach tables are read with :class:`vega_model.aero.ScalarTable` (bit-identical to
    ``numpy.interp``). One RK4 stage costs ≈ 3 µs instead of ≈ 20 µs with numpy scalars.
    """

    __slots__ = ("p", "_inputs", "_rates")

    def __init__(self, p: ModelParameters):
        self.p = p
        T, m, J = p.thrust_n, p.mass_kg, p.jyy_kgm2
        lc, d = p.l_cg_pvp_m, p.l_cp_m
        mn, ln, jn = p.nozzle_mass_kg, p.nozzle_lever_m, p.nozzle_inertia_kgm2
        tp0, tp1 = p.psi_t_pvp
        rp0, rp1 = p.psi_r_pvp
        w1, w2 = p.omega_radps
        v, a, s_ref = p.v_mps, p.sound_speed_mps, p.s_ref_m2
        half_rho = 0.5 * p.rho_kgpm3
        cn_alpha, c_a = p.aero.scalar_tables()
        k_cf = p.aero.crossflow_coefficient
        neg_mn_ln = -mn * ln
        neg_t, lc_t = -T, lc * T
        jn_rp0, jn_rp1 = jn * rp0, jn * rp1
        mode1_q, mode1_qd = -w1 * w1, 2.0 * p.zeta * w1
        mode2_q, mode2_qd = -w2 * w2, 2.0 * p.zeta * w2
        sin, cos, atan2, hypot = math.sin, math.cos, math.atan2, math.hypot
        # the Mach-table segments in use (ScalarTable.segment): Mach changes slowly, so the
        # search runs only when it leaves a segment
        n_lo, n_hi, n_slope, n_x, n_y = cn_alpha.segment(p.mach)
        a_lo, a_hi, a_slope, a_x, a_y = c_a.segment(p.mach)

        def inputs(beta, beta_dd, wind, beta_d):
            """The terms that depend on the inputs only."""
            sb, cb = sin(beta), cos(beta)
            # nozzle reaction at the pivot (nozzle CG l_N behind the pivot, rotated by β)
            fnx = neg_mn_ln * (beta_dd * sb + beta_d * beta_d * cb)
            fnz = neg_mn_ln * (beta_dd * cb - beta_d * beta_d * sb)
            # generalised modal force (thesis Eq. 2.28 terms, β through the actual angle)
            modal = neg_t * sb + fnz
            return (wind, beta, fnx, fnz, jn * beta_dd, lc * fnz, modal,
                    jn_rp0 * beta_dd, jn_rp1 * beta_dd)

        def rates(theta, theta_dot, z_dot, q1, q2, q1d, q2d, i):
            """θ̈, z̈, q̈1, q̈2 at one state for the input terms ``i``."""
            nonlocal n_lo, n_hi, n_slope, n_x, n_y, a_lo, a_hi, a_slope, a_x, a_y
            wind, beta, fnx, fnz, jn_bdd, lc_fnz, modal, in1, in2 = i
            # airflow at the CP (thesis Eqs. 2.9-2.10): air-relative velocity in the
            # reference frame (x along, z normal), then in body axes (u along the body axis)
            st, ct = sin(theta), cos(theta)
            vx = v - theta_dot * d * st
            vz = z_dot - wind - theta_dot * d * ct
            alpha = atan2(vx * st + vz * ct, vx * ct - vz * st)
            airspeed = hypot(vx, vz)
            mach = airspeed / a
            qbar_s = half_rho * airspeed * airspeed * s_ref
            if n_lo < mach < n_hi:
                cna = n_slope * (mach - n_x) + n_y
            else:
                cna = cn_alpha(mach)
                n_lo, n_hi, n_slope, n_x, n_y = cn_alpha.segment(mach)
            if a_lo < mach < a_hi:
                ca = a_slope * (mach - a_x) + a_y
            else:
                ca = c_a(mach)
                a_lo, a_hi, a_slope, a_x, a_y = c_a.segment(mach)
            sa = sin(alpha)
            normal = qbar_s * (cna * sa * cos(alpha) + k_cf * sa * abs(sa))
            axial = qbar_s * ca
            beta_eff = beta - (rp0 * q1 + rp1 * q2)
            offset = tp0 * q1 + tp1 * q2
            ce, se = cos(beta_eff), sin(beta_eff)
            fx = T * ce - axial + fnx
            fz = neg_t * se - normal + fnz
            moment = d * normal + T * ce * offset - lc_t * se - jn_bdd + lc_fnz
            return (moment / J,
                    (-fx * st + fz * ct) / m,
                    mode1_q * q1 - mode1_qd * q1d + tp0 * modal + in1,
                    mode2_q * q2 - mode2_qd * q2d + tp1 * modal + in2)

        self._inputs, self._rates = inputs, rates

    def derivatives(self, x, u) -> tuple[float, ...]:
        """State derivative at ``x`` (order :data:`STATES`) for inputs ``u``
        (:data:`NONLINEAR_INPUTS`; β̇ defaults to 0) as a tuple of floats."""
        theta, theta_dot, _z, z_dot, q1, q2, q1d, q2d = (float(v) for v in x)
        i = self._inputs(float(u[0]), float(u[1]), float(u[2]),
                         float(u[3]) if len(u) > 3 else 0.0)
        tdd, zdd, q1dd, q2dd = self._rates(theta, theta_dot, z_dot, q1, q2, q1d, q2d, i)
        return (theta_dot, tdd, z_dot, zdd, q1d, q2d, q1dd, q2dd)

    def rk4_step(self, x: tuple, u: tuple, h: float) -> tuple[float, ...]:
        """One classical RK4 step of length ``h`` [s] from state ``x`` (8 floats) with the
        inputs ``u = (β, β̈, v_w, β̇)`` held over the step; returns the new state.

        The same arithmetic, element by element, as ``k1 = f(x); k2 = f(x + h/2·k1); …;
        x + h/6·(k1 + 2(k2 + k3) + k4)`` on numpy arrays.
        """
        rates = self._rates
        i = self._inputs(*u)
        h2, h6 = 0.5 * h, h / 6.0
        th, thd, z, zd, q1, q2, q1d, q2d = x
        a1, b1, c1, d1 = rates(th, thd, zd, q1, q2, q1d, q2d, i)
        th2, thd2, zd2 = th + h2 * thd, thd + h2 * a1, zd + h2 * b1
        q12, q22, q1d2, q2d2 = q1 + h2 * q1d, q2 + h2 * q2d, q1d + h2 * c1, q2d + h2 * d1
        a2, b2, c2, d2 = rates(th2, thd2, zd2, q12, q22, q1d2, q2d2, i)
        th3, thd3, zd3 = th + h2 * thd2, thd + h2 * a2, zd + h2 * b2
        q13, q23, q1d3, q2d3 = q1 + h2 * q1d2, q2 + h2 * q2d2, q1d + h2 * c2, q2d + h2 * d2
        a3, b3, c3, d3 = rates(th3, thd3, zd3, q13, q23, q1d3, q2d3, i)
        th4, thd4, zd4 = th + h * thd3, thd + h * a3, zd + h * b3
        q14, q24, q1d4, q2d4 = q1 + h * q1d3, q2 + h * q2d3, q1d + h * c3, q2d + h * d3
        a4, b4, c4, d4 = rates(th4, thd4, zd4, q14, q24, q1d4, q2d4, i)
        return (th + h6 * (thd + 2.0 * (thd2 + thd3) + thd4),
                thd + h6 * (a1 + 2.0 * (a2 + a3) + a4),
                z + h6 * (zd + 2.0 * (zd2 + zd3) + zd4),
                zd + h6 * (b1 + 2.0 * (b2 + b3) + b4),
                q1 + h6 * (q1d + 2.0 * (q1d2 + q1d3) + q1d4),
                q2 + h6 * (q2d + 2.0 * (q2d2 + q2d3) + q2d4),
                q1d + h6 * (c1 + 2.0 * (c2 + c3) + c4),
                q2d + h6 * (d1 + 2.0 * (d2 + d3) + d4))


def ins_outputs(p: ModelParameters, x) -> np.ndarray:
    """INS-location pitch, pitch rate, drift and drift rate (thesis Eqs. 2.33-2.36).

    The INS sits l = x_INS − x_CG ahead of the CG; bending adds the local slope
    (subtracted, θ_local = θ − Σ Ψr q) and the local displacement (added).
    """
    return np.array(ins_outputs_tuple(p, x))


def ins_outputs_tuple(p: ModelParameters, x) -> tuple[float, float, float, float]:
    """:func:`ins_outputs` as a tuple of floats (the INS model's per-sample path)."""
    theta, theta_dot, z, z_dot, q1, q2, q1d, q2d = (float(v) for v in x)
    ri, ti, li = p.psi_r_ins, p.psi_t_ins, p.l_ins_m
    return (theta - ri[0] * q1 - ri[1] * q2,
            theta_dot - ri[0] * q1d - ri[1] * q2d,
            z - li * math.sin(theta) + ti[0] * q1 + ti[1] * q2,
            z_dot - li * math.cos(theta) * theta_dot + ti[0] * q1d + ti[1] * q2d)


def nonlinear_outputs(p: ModelParameters, x, u) -> np.ndarray:
    """Outputs ``[Qα, θ_INS, θ̇_INS, z_INS, ż_INS]`` of the nonlinear model.

    Qα = Q·α with Q the dynamic pressure of the actual airspeed at the CP and α the
    signed angle of attack there (thesis Eq. 2.18 in the pitch plane) [Pa·rad].
    """
    q_alpha = alpha_and_q_alpha(p, x, u[2])[1]
    return np.concatenate(([q_alpha], ins_outputs(p, x)))
