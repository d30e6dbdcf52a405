"""Wind-biased guidance: the reference deviations that fly a design wind at low structural load.

The nominal trajectory (docs/TRAJECTORY.md) is designed in still air. Holding it through the
steady wind V_w(h) (thesis Eq. 2.54) puts the whole wind into the angle of attack: Qα beyond its
envelope at Mach 0.31 (≈ 10.8 s) on the steady profile alone. Launchers instead bias the
first-stage steering to the expected wind (NASA TM-100375; docs/GUIDANCE.md). This module
computes that bias offline as a small optimal-control problem on the rigid-body part of the
vehicle model (:func:`vega_model.dynamics.linear_model`, states θ, θ̇, z, ż; input β; the
design wind as a known input), solved with cvxpy + Clarabel:

    minimise   Σ_k Δt [ (Qα_k / E(M_k))² + w_θ (θ_k / 1°)² + w_β (β_k / 1°)²
                        + w_Δβ (Δβ_k / Δt / (1°/s))² ]
    subject to x_{k+1} = Φ_k x_k + Γ_k β_k + Γw_k v_w,k   (exact zero-order hold, Δt = 0.1 s)
               x_0 = 0 (lift-off on the nominal),  |z_k| ≤ z_max,  |ż_k| ≤ ż_max

with E(M) the structural-load envelope of the requirements (vega_sim.requirements) and
v_w,k = V_w(h_nom(t_k)) along the nominal altitude. Output: the reference of the four INS
measurements (the rigid part of the model's INS rows) and the feed-forward β_k, exported with
provenance (:func:`write_guidance_reference`) and re-read through the flight software's loader.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import scipy.linalg as sla

from vega_gnc.guidance_reference import (FORMAT_VERSION, GuidanceReference,
                                         load_guidance_reference)
from vega_gnc.controller_table import MEASUREMENT_NAMES
from vega_model.dynamics import linear_model
from vega_model.parameters import ModelContext, default_context
from vega_model.vehicle_data import VehicleData
from vega_model.wind import WindTable, wind_profile_mps

from vega_loops.export import git_revision, library_versions, write_checked_npz

__all__ = ["GuidanceWeights", "DesignWind", "GuidanceDesign", "design_reference",
           "design_from_solution", "rigid_models", "write_guidance_reference",
           "hold_attitude_q_alpha", "plot_guidance"]


@dataclass(frozen=True)
class GuidanceWeights:
    """Weights and bounds of the guidance problem (docs/GUIDANCE.md §3).

    The load term is normalised by the envelope, so 1 = the requirement. Assumptions:
    ``theta_weight`` 0.1 per (1°)² keeps the bias near the nominal programme where the load is
    small (at lift-off the attitude would otherwise swing to the wind for a negligible load
    gain); ``beta_weight`` 1 per (1°)² and ``beta_rate_weight`` 0.01 per (1°/s)² keep the
    feed-forward small and smooth; the drift bounds are HALF the budget of thesis Table 3.1
    (500 m, 15 m/s), the other half left to the unforecast wind, turbulence and tracking.
    """

    theta_weight: float = 0.1
    beta_weight: float = 1.0
    beta_rate_weight: float = 0.01
    z_max_m: float = 250.0
    z_dot_max_mps: float = 7.5
    dt_s: float = 0.1
    t_end_s: float = 100.0


@dataclass(frozen=True)
class DesignWind:
    """The wind a reference is designed for: ``scale · V(h − shift_m)``, V the profile of
    Eq. 2.54 or, if ``table`` is given, that table (a day-of-launch sounding; linear in
    altitude, end values held: :class:`vega_model.wind.WindTable`, the law the plant flies)."""

    scale: float = 1.0
    shift_m: float = 0.0
    name: str = "thesis Eq. 2.54 steady profile V_w(h) (vehicle.yaml wind.profile)"
    table: WindTable | None = None

    @classmethod
    def from_table(cls, altitude_m, wind_mps, name: str = "measured profile (table)",
                   source: str = "") -> "DesignWind":
        """The design wind of a tabulated profile (altitudes [m], wind along +z [m/s]).

        Raises
        ------
        vega_model.wind.WindTableError
            One line naming the column and row of a malformed table."""
        return cls(name=name, table=WindTable(altitude_m, wind_mps, source))

    def along(self, altitudes_m, data: VehicleData) -> np.ndarray:
        """The design wind [m/s] at each of the altitudes ``altitudes_m`` [m]."""
        if self.table is None:
            return np.array([wind_profile_mps(h, data, self.scale, self.shift_m)
                             for h in altitudes_m])
        shifted = np.asarray(altitudes_m, dtype=float) - self.shift_m
        return self.scale * self.table.values(shifted)


@dataclass(frozen=True)
class GuidanceDesign:
    """A computed reference and its design flight (SI units, one row per time)."""

    t_s: np.ndarray
    states: np.ndarray              # (N, 4) θ, θ̇, z, ż of the reference flight
    reference: np.ndarray           # (N, 4) INS measurements, MEASUREMENT_NAMES order
    beta_ff_rad: np.ndarray         # (N,)
    wind_mps: np.ndarray            # (N,) design wind along +z
    q_alpha_pa_rad: np.ndarray      # (N,) Qα of the reference flight in the design wind
    q_alpha_hold_pa_rad: np.ndarray  # (N,) Qα holding the nominal attitude in the design wind
    envelope_pa_rad: np.ndarray     # (N,)
    mach: np.ndarray                # (N,)
    summary: dict[str, Any]


def rigid_models(times_s, context: ModelContext, dt_s: float):
    """Per time: ZOH transition (Φ, Γβ, Γw) of the rigid model, the Qα row and wind
    feed-through, the rigid INS rows, and the parameters."""
    phis, gam_b, gam_w, cq, dq, cins, params = [], [], [], [], [], [], []
    for t in times_s:
        p = context.parameters(float(t))
        A, B, C, D = linear_model(p)
        M = np.zeros((6, 6))
        M[:4, :4] = A[:4, :4]
        M[:4, 4] = B[:4, 0]
        M[:4, 5] = B[:4, 2]
        E = sla.expm(M * dt_s)
        phis.append(E[:4, :4])
        gam_b.append(E[:4, 4])
        gam_w.append(E[:4, 5])
        cq.append(C[0, :4])
        dq.append(D[0, 2])
        cins.append(C[1:5, :4])
        params.append(p)
    return (np.array(phis), np.array(gam_b), np.array(gam_w), np.array(cq), np.array(dq),
            np.array(cins), params)


def hold_attitude_q_alpha(times_s, wind: DesignWind = DesignWind(),
                          context: ModelContext | None = None) -> np.ndarray:
    """Qα [Pa·rad] of a vehicle that holds the nominal attitude and path (zero deviations)
    in the design wind: the load the guidance bias removes."""
    context = context if context is not None else default_context()
    params = [context.parameters(float(t)) for t in times_s]
    vw = wind.along([p.h_m for p in params], context.vehicle)
    return np.array([linear_model(p)[3][0, 2] * v for p, v in zip(params, vw)])


def design_reference(wind: DesignWind = DesignWind(),
                     weights: GuidanceWeights = GuidanceWeights(), *,
                     context: ModelContext | None = None, requirements=None,
                     progress: Callable[[str], None] = lambda _: None) -> GuidanceDesign:
    """Solve the guidance problem of the module docstring.

    Parameters
    ----------
    wind
        The design wind.
    weights
        Weights, drift bounds and the time grid.
    context
        Model data sources (default: the shipped vehicle data and flight conditions).
    requirements
        :class:`vega_sim.requirements.RequirementSpec` whose Qα envelope normalises the load
        (default: the shipped requirements).
    progress
        Called with one line per stage.

    Raises
    ------
    RuntimeError
        If the solver does not return an optimal solution (an internal error: the problem is
        feasible for any wind, the zero-wind reference being 0).
    """
    import cvxpy as cp

    from vega_sim.requirements import load_requirements

    context = context if context is not None else default_context()
    spec = requirements if requirements is not None else load_requirements()
    n_steps = int(round(weights.t_end_s / weights.dt_s))
    t = np.arange(n_steps + 1) * weights.dt_s
    t0 = time.perf_counter()
    phi, gb, gw, cq, dq, cins, params = rigid_models(t, context, weights.dt_s)
    vw = wind.along([p.h_m for p in params], context.vehicle)
    mach = np.array([p.mach for p in params])
    env = np.interp(mach, spec.envelope_mach, spec.envelope_pa_rad)
    progress(f"guidance: {t.size} rigid models ({time.perf_counter() - t0:.1f} s); "
             f"design wind max {np.abs(vw).max():.1f} m/s")

    deg = math.radians(1.0)
    x = cp.Variable((t.size, 4))
    beta = cp.Variable(t.size)
    cons = [x[0] == 0, cp.abs(x[:, 2]) <= weights.z_max_m,
            cp.abs(x[:, 3]) <= weights.z_dot_max_mps]
    cons += [x[k + 1] == phi[k] @ x[k] + gb[k] * beta[k] + gw[k] * vw[k]
             for k in range(n_steps)]
    qa = cp.sum(cp.multiply(cq, x), axis=1) + dq * vw
    dt = weights.dt_s
    cost = dt * (cp.sum_squares(cp.multiply(qa, 1.0 / env))
                 + weights.theta_weight * cp.sum_squares(x[:, 0] / deg)
                 + weights.beta_weight * cp.sum_squares(beta / deg)
                 + weights.beta_rate_weight * cp.sum_squares(cp.diff(beta) / dt / deg))
    problem = cp.Problem(cp.Minimize(cost), cons)
    t1 = time.perf_counter()
    problem.solve(solver="CLARABEL")
    solve_s = time.perf_counter() - t1
    if problem.status != "optimal":
        raise RuntimeError(f"guidance problem: solver status {problem.status}")
    progress(f"guidance: solved in {solve_s:.1f} s (cost {problem.value:.4g})")

    return design_from_solution(
        t, np.array(x.value), np.asarray(beta.value), vw, weights,
        (phi, gb, gw, cq, dq, cins, mach, env),
        {"name": "CLARABEL", "status": problem.status, "solve_s": solve_s,
         "cost": float(problem.value)})


def design_from_solution(t: np.ndarray, states: np.ndarray, b: np.ndarray, vw: np.ndarray,
                         weights: GuidanceWeights, models: tuple,
                         solver: Mapping[str, Any]) -> GuidanceDesign:
    """The :class:`GuidanceDesign` of a solved guidance problem: the INS reference, the load
    of the reference flight and of holding the nominal attitude, and the summary.

    ``states`` (N, 4) and ``b`` (N,) are the solver's; ``models`` = (Φ, Γβ, Γw, Qα row, Qα
    wind feed-through, INS rows, Mach, envelope) on the grid ``t``; ``solver`` goes to the
    summary as it is."""
    phi, gb, gw, cq, dq, cins, mach, env = models
    # The states as solved (not re-propagated from the feed-forward: the rigid body is
    # aerodynamically unstable, so an open-loop propagation amplifies the solver's residual);
    # the dynamics residual is recorded.
    states = np.array(states, dtype=float)
    states[0] = 0.0             # the constraint x_0 = 0, exactly (not to the solver's 1e-13)
    b = np.array(b, dtype=float)
    residual = states[1:] - (np.einsum("kij,kj->ki", phi[:-1], states[:-1])
                             + gb[:-1] * b[:-1, None] + gw[:-1] * vw[:-1, None])
    q_alpha = np.einsum("ij,ij->i", cq, states) + dq * vw
    reference = np.einsum("kij,kj->ki", cins, states)
    hold = dq * vw
    ratio = np.abs(q_alpha) / env
    ratio_hold = np.abs(hold) / env
    k, kh = int(ratio.argmax()), int(ratio_hold.argmax())
    summary = {
        "t_s": [float(t[0]), float(t[-1]), weights.dt_s],
        "design_q_alpha_ratio_max": float(ratio[k]), "design_q_alpha_ratio_time_s": float(t[k]),
        "hold_q_alpha_ratio_max": float(ratio_hold[kh]),
        "hold_q_alpha_ratio_time_s": float(t[kh]),
        "theta_max_deg": float(np.degrees(np.abs(states[:, 0]).max())),
        "z_max_m": float(np.abs(states[:, 2]).max()),
        "z_dot_max_mps": float(np.abs(states[:, 3]).max()),
        "beta_ff_max_deg": float(np.degrees(np.abs(b).max())),
        "wind_max_mps": float(np.abs(vw).max()),
        "dynamics_residual_max": [float(v) for v in np.abs(residual).max(axis=0)],
        "solver": dict(solver),
    }
    return GuidanceDesign(t_s=t, states=states, reference=reference, beta_ff_rad=b,
                          wind_mps=vw, q_alpha_pa_rad=q_alpha, q_alpha_hold_pa_rad=hold,
                          envelope_pa_rad=env, mach=mach, summary=summary)


def write_guidance_reference(path: str | Path, design: GuidanceDesign, wind: DesignWind,
                             weights: GuidanceWeights, *,
                             sources: Mapping[str, str] | None = None) -> GuidanceReference:
    """Write a guidance reference file atomically and re-read it through the flight
    software's loader (:func:`vega_gnc.guidance_reference.load_guidance_reference`); a JSON
    summary is written beside it (same name, ``.json``).

    Returns
    -------
    GuidanceReference
        The file as the flight software loads it.
    """
    meta = {
        "input_names": list(MEASUREMENT_NAMES),
        "units": {"t_s": "s", "reference": ["rad", "rad/s", "m", "m/s"], "beta_ff_rad": "rad"},
        "design_wind": asdict(wind),
        "weights": asdict(weights),
        "constraints": {"x0": "zero (lift-off on the nominal)",
                        "z_max_m": weights.z_max_m, "z_dot_max_mps": weights.z_dot_max_mps},
        "solver": design.summary["solver"],
        "summary": design.summary,
        "sources": dict(sources or {}),
        "versions": library_versions(),
        "git_revision": git_revision(),
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
    arrays = dict(
        format_version=np.array(FORMAT_VERSION), t_s=design.t_s, reference=design.reference,
        beta_ff_rad=design.beta_ff_rad, metadata=np.array(json.dumps(meta, sort_keys=True)),
        states=design.states, wind_mps=design.wind_mps, q_alpha_pa_rad=design.q_alpha_pa_rad,
        envelope_pa_rad=design.envelope_pa_rad)
    out = Path(path)
    write_checked_npz(out, arrays, load_guidance_reference)
    loaded = load_guidance_reference(out)
    out.with_suffix(".json").write_text(json.dumps(
        {k: meta[k] for k in ("design_wind", "weights", "constraints", "summary", "sources",
                              "git_revision", "created_utc", "versions")},
        indent=1, sort_keys=True) + "\n")
    return loaded


def plot_guidance(design: GuidanceDesign, path: str | Path) -> Path:
    """One figure of a reference: attitude, drift and rate, feed-forward, and Qα against the
    envelope for the reference flight and for holding the nominal attitude (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = design.t_s
    fig, ax = plt.subplots(4, 1, figsize=(9, 11), sharex=True)
    ax[0].plot(t, np.degrees(design.states[:, 0]), label="θ_ref (deviation from the nominal)")
    ax[0].plot(t, design.wind_mps, "--", label="design wind v_w [m/s]")
    ax[0].set_ylabel("deg  /  m/s")
    ax[1].plot(t, design.states[:, 2], label="z_ref [m]")
    ax[1].plot(t, 10 * design.states[:, 3], label="10 × ż_ref [m/s]")
    ax[1].set_ylabel("m")
    ax[2].plot(t, np.degrees(design.beta_ff_rad), label="β_ff")
    ax[2].set_ylabel("deg")
    ax[3].plot(t, np.degrees(np.abs(design.q_alpha_pa_rad)) / 1e3, label="|Qα| reference flight")
    ax[3].plot(t, np.degrees(np.abs(design.q_alpha_hold_pa_rad)) / 1e3,
               label="|Qα| holding the nominal attitude")
    ax[3].plot(t, np.degrees(design.envelope_pa_rad) / 1e3, "k--", label="envelope")
    ax[3].set_ylabel("kPa·deg")
    ax[3].set_xlabel("flight time [s]")
    for a in ax:
        a.grid(True, alpha=0.3)
        a.legend(loc="best", fontsize=8)
    fig.suptitle("Wind-biased guidance reference (design wind, rigid-body model)")
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
