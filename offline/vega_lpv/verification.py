"""Verification of a synthesised LPV controller, independent of the solver's own claims.

* :func:`dense_certificate` — the closed-loop certificate (docs/LPV_SYNTHESIS.md §5) on a grid
  denser than the synthesis grid, at every rate vertex, with the plant rebuilt from the model
  at each point.
* :func:`frozen_point_sweep` — closed-loop stability and the weighted H∞ norm (SLICOT ab13dd)
  at many flight times with the *interpolated* controller the flight software runs.
* :func:`loop_margins` — classical margins with the loop broken at the actuator input: rigid-
  body low- and high-frequency gain margins, phase margin, and the loop gain at both bending
  modes.

Scheduling: ρ = v. Along the trajectory v(t) is strictly increasing after lift-off, so a ρ
maps back to one flight time (:func:`time_at_velocity`), where the plant is built.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vega_lpv.certificate import certificate_check, closed_loop, hinf_norm
from vega_lpv.interconnection import plant_for_simulation, weighted_plant

__all__ = ["time_at_velocity", "bending_rate_term", "dense_certificate", "FrozenSweep",
           "frozen_point_sweep", "LoopMargins", "loop_margins"]


def time_at_velocity(v_mps, context):
    """Flight time(s) in 2–100 s at which the trajectory has velocity ``v_mps`` (clamped)."""
    fc = context.conditions
    t, v = fc.t_s, fc.column("v_mps")
    # v(t) is strictly increasing from lift-off (0.82 s) to burn-out; after ≈ 100 s the thrust
    # tails off and v(t) flattens, so the inverse is taken on 2–100 s only
    moving = (t >= 2.0) & (t <= 100.0)
    return np.interp(v_mps, v[moving], t[moving])


GRID_REFERENCE_T_S = 40.0   # any flight time: only the state names of M are needed


def _point(t_s, weights, context):
    return weighted_plant(float(t_s), weights, context).as_point()


def bending_rate_term(context, weights, h_s: float = 0.05):
    """N(ρ) of the frequency-normalised bending coordinates η_i = ω_i(ρ) q_i of M(ρ).

    Along a trajectory η̇_i = ω_i q̇_i + (ω̇_i/ω_i) η_i with ω̇_i = ρ̇ dω_i/dρ, so the exact LPV
    model in these coordinates is ẋ = (A(ρ) + ρ̇ N(ρ)) x + …, N = diag((dω_i/dρ)/ω_i) on the η
    states (interconnection._frequency_normalised_bending). The synthesis leaves N out; the
    certificate with it (certificate_check's ``rate_term``) covers the physical model.
    dω/dρ is a central difference along the trajectory: (dω/dt)/(dv/dt).
    """
    names = weighted_plant(GRID_REFERENCE_T_S, weights, context).state_names
    fc = context.conditions

    def rate_term(rho):
        t = float(time_at_velocity(rho, context))
        lo, hi = context.parameters(t - h_s), context.parameters(t + h_s)
        mid = context.parameters(t)
        dv = float(np.interp(t + h_s, fc.t_s, fc.column("v_mps"))
                   - np.interp(t - h_s, fc.t_s, fc.column("v_mps")))
        N = np.zeros((len(names), len(names)))
        for mode in (0, 1):
            i = names.index(f"eta{mode + 1}")
            N[i, i] = (hi.omega_radps[mode] - lo.omega_radps[mode]) / dv / mid.omega_radps[mode]
        return N
    return rate_term


def dense_certificate(result, weights, context, factor: int = 4, controller: str = "exact",
                      physical_rates: bool = False):
    """Certificate eigenvalues on a grid ``factor``× denser (in flight time) than the synthesis'.

    With ``physical_rates`` the plant includes the bending coordinates' rate term
    (:func:`bending_rate_term`).

    Returns
    -------
    times_s, rho, worst : np.ndarray
        ``worst[i, j]`` at ρ_i and rate vertex j (negative = certified).
    """
    t_grid = time_at_velocity(result.rho, context)
    times = np.concatenate([np.linspace(a, b, factor, endpoint=False)
                            for a, b in zip(t_grid[:-1], t_grid[1:])] + [t_grid[-1:]])
    rho = np.interp(times, context.conditions.t_s, context.conditions.column("v_mps"))
    rho = np.clip(rho, result.rho[0], result.rho[-1])
    cache = {}

    def plant_at(r):
        key = float(r)
        if key not in cache:
            cache[key] = _point(time_at_velocity(key, context), weights, context)
        return cache[key]

    vertices = result.rate_vertices or (0.0,)
    rate_term = bending_rate_term(context, weights) if physical_rates else None
    worst = certificate_check(plant_at, result, rho, vertices, controller=controller,
                              rate_term=rate_term)
    return times, rho, worst


@dataclass(frozen=True)
class FrozenSweep:
    """Frozen-time closed loops along the flight (interpolated controller)."""

    times_s: np.ndarray
    rho: np.ndarray
    rate_mps2: float
    max_real_eig: np.ndarray
    hinf: np.ndarray

    @property
    def all_stable(self) -> bool:
        """Every frozen closed loop is stable."""
        return bool(np.all(self.max_real_eig < 0.0))

    @property
    def worst_hinf(self) -> float:
        """Largest weighted H∞ norm over the sweep."""
        return float(np.max(self.hinf))


def frozen_point_sweep(result, weights, context, times_s, rate_mps2: float) -> FrozenSweep:
    """Stability and weighted H∞ norm of F_l(M(t), K(v(t), ρ̇)) at each time.

    K is the linear interpolation in ρ of the grid controllers (what the exported table
    flies), at the given ρ̇ slice.
    """
    times = np.asarray(times_s, dtype=float)
    rho = np.interp(times, context.conditions.t_s, context.conditions.column("v_mps"))
    eig = np.empty(times.size)
    norms = np.empty(times.size)
    for i, (t, r) in enumerate(zip(times, rho)):
        point = _point(t, weights, context)
        K = result.controller(float(np.clip(r, result.rho[0], result.rho[-1])), rate_mps2)
        A, B, C, D = closed_loop(point, K)
        eig[i] = np.max(np.linalg.eigvals(A).real)
        norms[i] = hinf_norm(A, B, C, D) if eig[i] < 0 else np.inf
    return FrozenSweep(times, rho, float(rate_mps2), eig, norms)


@dataclass(frozen=True)
class LoopMargins:
    """Classical margins at the actuator input (loop broken at u), at one flight time.

    Gain margins are factors (dB in :meth:`as_dict`): ``gm_low`` is the gain *reduction* the
    loop tolerates (the rigid body is unstable, so the loop is conditionally stable), ``gm_high``
    the gain increase; ``pm_deg`` the smallest phase margin over the gain crossovers;
    ``bending_gain_db`` the peak loop gain within ±20 % of each bending frequency
    (< 0 dB: the mode is gain-stabilised).
    """

    t_s: float
    gm_low: float
    gm_high: float
    pm_deg: float
    crossover_radps: float
    bending_gain_db: tuple[float, float]

    def as_dict(self) -> dict:
        """Rounded values in dB and degrees."""
        db = lambda g: float(20 * np.log10(g)) if np.isfinite(g) and g > 0 else float("inf")  # noqa: E731
        return {"t_s": self.t_s, "gm_low_db": db(self.gm_low), "gm_high_db": db(self.gm_high),
                "pm_deg": self.pm_deg, "crossover_radps": self.crossover_radps,
                "bending1_gain_db": self.bending_gain_db[0],
                "bending2_gain_db": self.bending_gain_db[1]}


def loop_margins(result, context, t_s: float, rate_mps2: float,
                 w_radps=None) -> LoopMargins:
    """Margins of L(jω) = −K(jω) P_yu(jω) (plant without weights, thesis §5.1), on the
    frequency grid ``w_radps`` [rad/s] (default: 6000 points log-spaced over 1e-3 … 10^3.3)."""
    if w_radps is None:
        w_radps = np.logspace(-3, 3.3, 6000)
    plant = plant_for_simulation(t_s, context)
    p = context.parameters(t_s)
    n_u = 1
    A, B2 = plant.A, plant.B[:, -n_u:]
    ny = 4
    C2, D22 = plant.C[-ny:], plant.D[-ny:, -n_u:]
    v = float(np.clip(p.v_mps, result.rho[0], result.rho[-1]))
    Ak, Bk, Ck, Dk = result.controller(v, rate_mps2)

    def response(M_A, M_B, M_C, M_D, w):
        eye = np.eye(M_A.shape[0])
        return np.array([M_C @ np.linalg.solve(1j * x * eye - M_A, M_B) + M_D for x in w])

    P = response(A, B2, C2, D22, w_radps)          # (nw, 4, 1)
    K = response(Ak, Bk, Ck, Dk, w_radps)          # (nw, 1, 4)
    L = -np.einsum("kij,kjl->k", K, P)             # SISO loop at the actuator input
    mag, phase = np.abs(L), np.unwrap(np.angle(L))
    # phase crossovers: phase = −180° (mod 360°)
    shifted = (phase + np.pi) / (2 * np.pi)
    gm_low, gm_high = 0.0, np.inf
    for k in np.nonzero(np.floor(shifted[:-1]) != np.floor(shifted[1:]))[0]:
        g = 1.0 / mag[k]
        if mag[k] > 1.0:
            gm_low = max(gm_low, g)        # reduction tolerated (factor < 1)
        else:
            gm_high = min(gm_high, g)
    pm, wc = np.inf, float("nan")
    for k in np.nonzero((mag[:-1] - 1.0) * (mag[1:] - 1.0) < 0)[0]:
        margin = np.degrees(np.abs(np.angle(-L[k])))  # distance of the phase from −180°
        if margin < pm:
            pm, wc = margin, float(w_radps[k])
    # peak loop gain within ±20 % of each bending frequency (the resonance peak)
    bend = tuple(float(20 * np.log10(mag[(w_radps > 0.8 * w0) & (w_radps < 1.2 * w0)].max()))
                 for w0 in p.omega_radps)
    return LoopMargins(float(t_s), gm_low if gm_low > 0 else float("nan"), gm_high,
                       float(pm), wc, bend)
