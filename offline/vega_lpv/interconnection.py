"""The weighted interconnection M(ρ) of the LPV synthesis and the unweighted loop plant.

Thesis §4.4–4.5 (Figs. 4.5, 4.7): the generalised plant around the launcher model
G_LV (vega_plant, thesis Eq. 2.44 re-derived, docs/MODEL.md) with the TVC actuator and
the Padé delay in the loop, the wind filter, and the input and output weights of a
:class:`~vega_lpv.weights.WeightSet`. Diagram, signal orders and every weight:
docs/SYNTHESIS_WEIGHTS.md.

* :func:`weighted_plant` — M(ρ) at one grid point (19 states with the two W_β notches):
  w = [w_c (4), w_w, w_n (4)] (normalised), u = β_cmd [rad],
  e = [θ error, θ_INS (T bound), z_INS, ż_INS, Qα, β_cmd] (normalised),
  y = r − (y_INS + n) = command minus measured [θ, θ̇, z, ż].
* :func:`plant_for_simulation` — the same loop without weights (thesis §5.1:
  z = F_l(P(ρ), K(ρ)) w), in physical units, for closed-loop simulation and verification.

The scheduling parameter is ρ = v (m/s); a grid point is named by its flight time t on
the reference trajectory, and every parameter of M comes from ``model_parameters(t)``
(thesis §4.3.1: all parameters are functions of v along the fixed trajectory).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vega_model.actuator import ActuatorParams, linear_actuator_ss
from vega_model.delay import DelayParams, pade_ss
from vega_model.dynamics import STATES, linear_model
from vega_model.parameters import ModelContext, ModelParameters, default_context
from vega_model.vehicle_data import VehicleData
from vega_model.wind import turbulence_params, wind_profile_mps

from vega_loops.margins import cascade
from vega_lpv.weights import THESIS, WeightSet

__all__ = ["GRID_TIMES_S", "GeneralizedPlant", "weighted_plant", "plant_for_simulation",
           "weight_ss", "W_INPUTS", "W_OUTPUTS", "Y_NAMES"]

GRID_TIMES_S = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0)  # thesis §4.3.2

_DEG = math.pi / 180.0

# Signal names (orders) of M(ρ).
W_INPUTS = ("w_theta_cmd", "w_theta_dot_cmd", "w_z_cmd", "w_z_dot_cmd", "w_wind",
            "w_noise_theta", "w_noise_theta_dot", "w_noise_z", "w_noise_z_dot")
W_OUTPUTS = ("e_theta_error", "e_theta_ins", "e_z_ins", "e_z_dot_ins", "e_q_alpha",
             "e_beta_cmd")
Y_NAMES = ("y_theta_err_rad", "y_theta_dot_err_radps", "y_z_err_m", "y_z_dot_err_mps")
_U_NAME = "u_beta_cmd_rad"


@dataclass(frozen=True)
class GeneralizedPlant:
    """A generalised plant P = [A B; C D] with inputs [w; u] and outputs [e; y].

    Attributes
    ----------
    A, B, C, D
        State-space matrices; B = [B1 B2], C = [C1; C2] partitioned by
        ``n_w, n_u, n_e, n_y``.
    n_w, n_u, n_e, n_y
        Numbers of exogenous inputs, controls, performance outputs, measurements.
    state_names, input_names, output_names
        Names in matrix order (inputs: w then u; outputs: e then y).
    t_s, rho_mps
        Flight time of the grid point [s] and the scheduling parameter ρ = v [m/s].
    weights
        The weight set of M(ρ), or None for the unweighted simulation plant.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    n_w: int
    n_u: int
    n_e: int
    n_y: int
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    t_s: float
    rho_mps: float
    weights: WeightSet | None

    @property
    def n_x(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    @property
    def B1(self) -> np.ndarray:
        """Exogenous-input matrix (n_x × n_w)."""
        return self.B[:, :self.n_w]

    @property
    def B2(self) -> np.ndarray:
        """Control-input matrix (n_x × n_u)."""
        return self.B[:, self.n_w:]

    @property
    def C1(self) -> np.ndarray:
        """Performance-output matrix (n_e × n_x)."""
        return self.C[:self.n_e]

    @property
    def C2(self) -> np.ndarray:
        """Measurement matrix (n_y × n_x)."""
        return self.C[self.n_e:]

    @property
    def D11(self) -> np.ndarray:
        """w → e feedthrough."""
        return self.D[:self.n_e, :self.n_w]

    @property
    def D12(self) -> np.ndarray:
        """u → e feedthrough."""
        return self.D[:self.n_e, self.n_w:]

    @property
    def D21(self) -> np.ndarray:
        """w → y feedthrough."""
        return self.D[self.n_e:, :self.n_w]

    @property
    def D22(self) -> np.ndarray:
        """u → y feedthrough."""
        return self.D[self.n_e:, self.n_w:]

    def as_point(self):
        """The same plant as the synthesis engine's :class:`~.gridded_plant.PlantPoint`."""
        from vega_lpv.gridded_plant import PlantPoint

        return PlantPoint(self.A, self.B, self.C, self.D, self.n_w, self.n_u, self.n_e, self.n_y)

    def close_loop(self, Ak, Bk, Ck, Dk) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Lower LFT F_l(P, K) with u = K y (thesis Eq. 2.47, Eq. 4.4).

        Parameters
        ----------
        Ak, Bk, Ck, Dk
            Controller from y (n_y) to u (n_u); Ak may be 0×0 (static gain).

        Returns
        -------
        A, B, C, D
            Closed loop from w to e, states [x; x_K].

        Raises
        ------
        ValueError
            If I − D22·Dk is singular (ill-posed loop).
        """
        Dk = np.atleast_2d(np.asarray(Dk, dtype=float))
        nk = np.shape(Ak)[0]
        Ak = np.asarray(Ak, dtype=float).reshape(nk, nk)
        Bk = np.asarray(Bk, dtype=float).reshape(nk, self.n_y)
        Ck = np.asarray(Ck, dtype=float).reshape(self.n_u, nk)
        m = np.eye(self.n_y) - self.D22 @ Dk
        if np.linalg.cond(m) > 1e12:
            raise ValueError("ill-posed loop: I - D22 Dk is singular")
        # y = R (C2 x + D21 w + D22 Ck xk), u = Ck xk + Dk y, with R = (I − D22 Dk)⁻¹
        R = np.linalg.inv(m)
        y_x, y_xk, y_w = R @ self.C2, R @ self.D22 @ Ck, R @ self.D21
        u_x, u_xk, u_w = Dk @ y_x, Ck + Dk @ y_xk, Dk @ y_w
        A = np.block([[self.A + self.B2 @ u_x, self.B2 @ u_xk],
                      [Bk @ y_x, Ak + Bk @ y_xk]])
        B = np.vstack([self.B1 + self.B2 @ u_w, Bk @ y_w])
        C = np.hstack([self.C1 + self.D12 @ u_x, self.D12 @ u_xk])
        D = self.D11 + self.D12 @ u_w
        return A, B, C, D


class _Signals:
    """Linear signal algebra on z = [x; inputs]: every signal is a row block acting on z.

    States and inputs are allocated by name; a subsystem's derivative rows are stored
    under its state block's name and assembled in allocation order by :meth:`matrices`.
    """

    def __init__(self, states: list[tuple[str, int]], inputs: list[tuple[str, int]]):
        self.n = sum(k for _, k in states)
        self.m = sum(k for _, k in inputs)
        eye = np.eye(self.n + self.m)
        self.x, self.inp, offset = {}, {}, 0
        for name, k in states:
            self.x[name] = eye[offset:offset + k]
            offset += k
        for name, k in inputs:
            self.inp[name] = eye[offset:offset + k]
            offset += k
        self._order = [name for name, _ in states]
        self.dx: dict[str, np.ndarray] = {}

    def system(self, name: str, ss, u_rows: np.ndarray) -> np.ndarray:
        """Drive state block ``name`` with A, B, C, D = ``ss`` from ``u_rows``; return y rows."""
        A, B, C, D = ss
        self.dx[name] = A @ self.x[name] + B @ u_rows
        return C @ self.x[name] + D @ u_rows

    def matrices(self, outputs: np.ndarray):
        """A, B, C, D with the given output rows (state order = allocation order)."""
        dx = np.vstack([self.dx[name] for name in self._order])
        return dx[:, :self.n], dx[:, self.n:], outputs[:, :self.n], outputs[:, self.n:]


def _launcher_loop(sig: _Signals, p: ModelParameters, ctx: ModelContext, u, v_w):
    """Padé delay → TVC actuator → G_LV, driven by the command ``u`` and wind ``v_w`` rows.

    Returns the rows of [Qα, θ_INS, θ̇_INS, z_INS, ż_INS] and of the nozzle angle β.
    """
    delay = DelayParams.from_vehicle(ctx.vehicle)
    u_delayed = sig.system("pade", pade_ss(delay.total_s, delay.pade_order), u)
    act = sig.system("actuator", linear_actuator_ss(ActuatorParams.from_vehicle(ctx.vehicle)),
                     u_delayed)
    beta, beta_ddot = act[[0]], act[[2]]
    y_lv = sig.system("plant", linear_model(p), np.vstack([beta, beta_ddot, v_w]))
    return y_lv, beta


def _loop_state_blocks(ctx: ModelContext) -> tuple[list[tuple[str, int]], tuple[str, ...]]:
    """State blocks of the loop (plant, actuator, Padé) and their state names."""
    order = DelayParams.from_vehicle(ctx.vehicle).pade_order
    names = STATES + ("act_beta_rad", "act_beta_dot_radps") + tuple(
        f"pade_{i + 1}" for i in range(order))
    return [("plant", 8), ("actuator", 2), ("pade", order)], names


def _lead_lag(zero: float, pole: float):
    """(s + zero)/(s + pole) = 1 + (zero − pole)/(s + pole), balanced input/output gains."""
    g = math.sqrt(abs(zero - pole))
    return (np.array([[-pole]]), np.array([[g]]), np.array([[math.copysign(g, zero - pole)]]),
            np.array([[1.0]]))


def _notch_inverse(omega: float, depth: float, width: float):
    """(s² + width·s + ω²)/(s² + depth·s + ω²) = 1 + (width − depth)s/(s² + depth·s + ω²).

    Realised with the rotation-like A = [[0, ω], [−ω, −depth]] (both states in the same
    units, entries ~ω) and equal input/output gains √(width − depth).
    """
    g = math.sqrt(width - depth)
    return (np.array([[0.0, omega], [-omega, -depth]]), np.array([[0.0], [g]]),
            np.array([[0.0, g]]), np.array([[1.0]]))


def _wind_filter(p: ModelParameters, data: VehicleData, weights: WeightSet):
    """Wind channel w_w → v_w [m/s], one state (see :func:`weight_ss`)."""
    sigma, ell = turbulence_params(p.h_m, data, weights.turbulence_intensity)
    sigma_max = float(np.max(data[f"wind.dryden.sigma_{weights.turbulence_intensity}_mps"]))
    sigma = max(sigma, weights.wind_floor * sigma_max)
    corner = p.v_mps / ell
    if weights.wind_channel == "dryden":
        b = weights.wind_sigmas * sigma * math.sqrt(2.0 * corner / math.pi)
        gain = math.sqrt(b)
        return (np.array([[-corner]]), np.array([[gain]]), np.array([[gain]]),
                np.zeros((1, 1)))
    dc = float(wind_profile_mps(p.h_m, data)) + weights.wind_sigmas * sigma
    gain = math.sqrt(dc * corner)
    return np.array([[-corner]]), np.array([[gain]]), np.array([[gain]]), np.zeros((1, 1))


# Bending displacement states of G_LV and their names in M(ρ) (η_i = ω_i(ρ) q_i).
_BENDING_STATES = (("q1", "eta1"), ("q2", "eta2"))


def _frequency_normalised_bending(A, B, C, names, omega_radps):
    """Bending displacements q_i → η_i = ω_i(ρ) q_i in M(ρ); ``names`` is renamed in place.

    In (η_i, q̇_i) a bending mode is the rotation-like block [[0, ω_i], [−ω_i, −2ζω_i]], the
    form of the W_β notch sections: a constant Lyapunov matrix (the identity) serves the
    mode at every frequency, while in (q_i, q̇_i) the mode's energy metric diag(ω_i², 1)
    changes along the flight and a ρ-independent or slowly varying X(ρ), Y(ρ) cannot follow
    it (docs/SYNTHESIS.md §2: with Clarabel's regularisation retry this is what made the
    9-point LMIs of the real plant solve; the run without it was not completed).

    The change is a frozen-point similarity x = T(ρ) x_η: every frozen plant keeps its
    transfer function, and the frozen-point checks are unaffected. Along a trajectory the
    LPV model in η gains the rate term ρ̇ (dT⁻¹/dρ) T, i.e. η̇_i = ω_i q̇_i + (ω̇_i/ω_i) η_i
    (|ω̇_i/ω_i| ≤ 8e-3 1/s on 10–90 s against the modes' decay ζω_i ≥ 0.24 1/s). Small, but
    not negligible for the certificate: the synthesis takes it in as ``GriddedPlant.N``
    (pipeline.gridded_plant, verification.bending_rate_term).
    """
    T = np.ones(A.shape[0])
    for (old, new), omega in zip(_BENDING_STATES, omega_radps):
        i = names.index(old)
        T[i] = 1.0 / omega                                   # q_i = η_i / ω_i
        names[i] = new
    return A * (1.0 / T)[:, None] * T[None, :], B / T[:, None], C * T[None, :]


def weight_ss(name: str, p: ModelParameters, weights: WeightSet = THESIS,
              vehicle: VehicleData | None = None):
    """State-space realisation of a dynamic weight at one grid point.

    Parameters
    ----------
    name
        ``"theta_z"`` — W_θz(s) of Eq. 4.21, input θ_INS [rad];
        ``"beta"`` — W_β(s, ρ) of Eq. 4.26, input β_cmd [rad] (LP section first, then the
        notch sections at ω_q1, ω_q2);
        ``"wind"`` — the wind channel w_w → v_w [m/s] including W_w (see Notes).
    p
        Model parameters at the grid point (bending frequencies for W_β; altitude and
        airspeed for the wind channel).
    weights
        The weight set.
    vehicle
        Vehicle data for the wind tables (default: the shipped vehicle data).

    Returns
    -------
    A, B, C, D : numpy.ndarray
        SISO realisation; W_θz and W_β outputs are normalised (1 = the bound of the
        requirement).

    Notes
    -----
    W_θz(s) = (π/180 · (h_θ s + ω_θ)/(s + ω_θ/l_θ))⁻¹ (Eq. 4.21): DC 1/(l_θ °),
    high frequency 1/(h_θ °), one state. Written as (π/180 · h_θ)⁻¹ · (s + ω_θ/l_θ)/(s + ω_θ/h_θ)
    — a unit-high-frequency-gain lead-lag and the weight's gain on the output.

    W_β(s, ρ) = (π/180 · N1(s) N2(s) LP(s))⁻¹ with N_i = (s² + 0.5 s + ω_qi²)/(s² + 70 s +
    ω_qi²) and LP = (h_u s + ω_u)/(s + ω_u/l_u), ω_u = ω_q1 (Eqs. 4.25–4.26): DC
    1/(l_u °), high frequency 1/(h_u °), gain 140× the LP value at each bending frequency
    (times the other notch's gain there). Each section is realised separately
    (1 + 2 + 2 states) with unit high-frequency gain and balanced input/output gains, and
    the gain (π/180 · h_u)⁻¹ is applied to the output, so every entry of A is of the order of
    the section's own frequencies.

    The wind channel (one state) is, for ``wind_channel = "dryden"``,
    W_w·σ_w √(2V/(πL_w)) / (s + V/L_w) — Eq. 2.53 with the airspeed V
    (vega_model.wind.dryden_ss, docs/MODEL.md) scaled by W_w = ``wind_sigmas``; for
    ``"profile"``, (V_w(h) + W_w σ_w(h)) · (V/L_w)/(s + V/L_w) — DC gain covering the
    steady profile of Eq. 2.54 plus W_w σ of turbulence, corner V/L_w. σ_w is floored at
    ``wind_floor`` × the largest σ_w of Table 2.4 (the intensity's column), so that the
    channel never vanishes (above 20 km σ_w = V_w = 0).
    """
    w = weights
    if name == "wind":
        return _wind_filter(p, vehicle or default_context().vehicle, w)
    if name == "theta_z":
        om, h, ll = w.theta_bandwidth_radps, w.theta_hf_deg, w.theta_lf_deg
        ss = _lead_lag(om / ll, om / h)
        gain = 1.0 / (h * _DEG)
    elif name == "beta":
        w1, w2 = p.omega_radps
        om, h, ll = w.beta_bandwidth_scale * w1, w.beta_hf_deg, w.beta_lf_deg
        ss = _lead_lag(om / ll, om / h)
        if w.notches:
            for omega in (w1, w2):
                ss = cascade(ss, _notch_inverse(omega, w.notch_numerator_radps,
                                                 w.notch_denominator_radps))
        gain = 1.0 / (h * _DEG)
    else:
        raise ValueError(f"unknown weight {name!r} (expected 'theta_z', 'beta' or 'wind')")
    A, B, C, D = ss
    return A, B, gain * C, gain * D


def weighted_plant(t_s: float, weights: WeightSet = THESIS,
                   context: ModelContext | None = None) -> GeneralizedPlant:
    """The weighted interconnection M(ρ) at flight time ``t_s`` (thesis Figs. 4.5, 4.7).

    Parameters
    ----------
    t_s
        Flight time of the grid point [s]; ρ = v(t_s).
    weights
        Weight set (default :data:`~vega_lpv.weights.THESIS`).
    context
        Model data sources (default: the shipped vehicle data and flight conditions).

    Returns
    -------
    GeneralizedPlant
        n_w = 9, n_u = 1, n_e = 6, n_y = 4; 19 states with the W_β notches (plant 8,
        actuator 2, Padé 2, wind 1, W_θz 1, W_β 5), 15 without.

    Notes
    -----
    Signals (docs/SYNTHESIS_WEIGHTS.md §1)::

        r   = W_c w_c,  W_c = diag(π/180, π/180, 1, 1)·(command sizes)        Eq. 4.17
        n   = W_n w_n,  W_n = diag(INS noise)                                 Eq. 4.18
        v_w = G_wind(s) w_w  (W_w = 3 σ)                                  Eq. 2.53, §4.5.1
        β, β̈ = G_TVC(s) e^{−sτ}(Padé) u;  y_LV = G_LV [β, β̈, v_w]          Eq. 2.44
        y   = r − (y_INS + n)
        e   = [W_θe (θ_c − θ_INS), W_θz(s) θ_INS, W_z z_INS, W_ż ż_INS,
               W_Qα(ρ) Qα, W_β(s, ρ) u]                              Eqs. 4.20–4.26

    with W_θe = (π/180·‖S_θ‖)⁻¹, W_z = 1/z_max, W_ż = 1/ż_max and
    W_Qα = 1/(α_max[rad]·Q(ρ)) (our Qα output is in Pa·rad). W_θ̇ = 0 (thesis §4.5.2), so
    that channel is left out. W_β acts on the command u, so D12 ≠ 0.
    """
    ctx = context or default_context()
    p = ctx.parameters(t_s)
    w = weights
    wbeta = weight_ss("beta", p, w)
    n_beta = wbeta[0].shape[0]
    loop_blocks, loop_names = _loop_state_blocks(ctx)
    sig = _Signals(loop_blocks + [("wind", 1), ("w_theta_z", 1), ("w_beta", n_beta)],
                   [("w_c", 4), ("w_w", 1), ("w_n", 4), ("u", 1)])
    u = sig.inp["u"]
    v_w = sig.system("wind", weight_ss("wind", p, w, ctx.vehicle), sig.inp["w_w"])
    y_lv, _ = _launcher_loop(sig, p, ctx, u, v_w)
    q_alpha, ins = y_lv[[0]], y_lv[1:5]

    data = ctx.vehicle
    w_c = np.diag([w.command_theta_deg * _DEG, w.command_theta_dot_degps * _DEG,
                   w.command_z_m, w.command_z_dot_mps])
    w_n = w.noise_scale * np.diag([data["ins.noise_pitch_rad"],
                                   data["ins.noise_pitch_rate_radps"],
                                   data["ins.noise_drift_m"], data["ins.noise_drift_rate_mps"]])
    r = w_c @ sig.inp["w_c"]
    y = r - ins - w_n @ sig.inp["w_n"]

    e = np.vstack([
        (r[[0]] - ins[[0]]) / (w.sensitivity_peak * _DEG),                 # Eq. 4.20
        sig.system("w_theta_z", weight_ss("theta_z", p, w), ins[[0]]),     # Eq. 4.21
        ins[[2]] / w.z_max_m,                                              # Eq. 4.22
        ins[[3]] / w.z_dot_max_mps,                                        # Eq. 4.22
        q_alpha / (w.alpha_max_deg * _DEG * max(p.q_pa, w.q_alpha_q_floor_pa)),  # Eq. 4.24
        sig.system("w_beta", wbeta, u),                                    # Eq. 4.26
    ])
    A, B, C, D = sig.matrices(np.vstack([e, y]))
    names = list(loop_names)
    A, B, C = _frequency_normalised_bending(A, B, C, names, p.omega_radps)
    beta_states = ["w_beta_lp"] + ([f"w_beta_notch{i}_{k}" for i in (1, 2) for k in "ab"]
                                   if w.notches else [])
    return GeneralizedPlant(
        A=A, B=B, C=C, D=D, n_w=9, n_u=1, n_e=6, n_y=4,
        state_names=tuple(names) + ("wind_filter", "w_theta_z") + tuple(beta_states),
        input_names=W_INPUTS + (_U_NAME,), output_names=W_OUTPUTS + Y_NAMES,
        t_s=float(t_s), rho_mps=p.v_mps, weights=w)


def plant_for_simulation(t_s: float, context: ModelContext | None = None) -> GeneralizedPlant:
    """The unweighted loop plant P(ρ) at flight time ``t_s`` (thesis §5.1).

    Parameters
    ----------
    t_s
        Flight time [s].
    context
        Model data sources (default: shipped data).

    Returns
    -------
    GeneralizedPlant
        12 states (plant 8, actuator 2, Padé 2), ``weights = None``; physical units:
        inputs w = [r (θ_c, θ̇_c, z_c, ż_c), v_w, n (4)] (n_w = 9) and u = β_cmd
        [rad]; outputs e = [Qα (Pa·rad), θ_INS, θ̇_INS, z_INS, ż_INS, β (rad)] (n_e = 6)
        and y = r − (y_INS + n) (n_y = 4), the same measurement as in M(ρ). Closing it
        with a controller synthesised on M(ρ) (:meth:`GeneralizedPlant.close_loop`)
        gives z = F_l(P(ρ), K(ρ)) w of thesis §5.1.
    """
    ctx = context or default_context()
    p = ctx.parameters(t_s)
    loop_blocks, loop_names = _loop_state_blocks(ctx)
    sig = _Signals(loop_blocks, [("r", 4), ("v_w", 1), ("n", 4), ("u", 1)])
    y_lv, beta = _launcher_loop(sig, p, ctx, sig.inp["u"], sig.inp["v_w"])
    y = sig.inp["r"] - y_lv[1:5] - sig.inp["n"]
    A, B, C, D = sig.matrices(np.vstack([y_lv, beta, y]))
    return GeneralizedPlant(
        A=A, B=B, C=C, D=D, n_w=9, n_u=1, n_e=6, n_y=4, state_names=loop_names,
        input_names=("theta_cmd_rad", "theta_dot_cmd_radps", "z_cmd_m", "z_dot_cmd_mps",
                     "wind_mps", "noise_theta_rad", "noise_theta_dot_radps", "noise_z_m",
                     "noise_z_dot_mps", _U_NAME),
        output_names=("q_alpha_pa_rad", "theta_ins_rad", "theta_dot_ins_radps", "z_ins_m",
                      "z_dot_ins_mps", "beta_rad") + Y_NAMES,
        t_s=float(t_s), rho_mps=p.v_mps, weights=None)
