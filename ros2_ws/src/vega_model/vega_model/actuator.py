"""TVC actuator: the second-order nozzle servo with position and rate limits.

Two views of one actuator (thesis §2.12.3; the thesis' code uses
G_TVC(s) = ω²/(s² + 2ζω s + ω²) with ω = 100 rad/s, ζ = 0.5):

* :func:`linear_actuator_ss` — the unlimited continuous-time model with outputs
  [β, β̇, β̈], for the synthesis and the linear analyses;
* :class:`TvcActuator` — the nonlinear discrete-time actuator stepped at the physics rate
  (1 kHz), with the position limit of thesis Table 3.1 (|β| ≤ 6.5°) and a rate limit
  (an assumption, ``actuator.rate_limit_radps`` in vehicle.yaml; the thesis gives none).

All numbers come from the ``actuator`` section of the vehicle data file.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np

from vega_model.vehicle_data import VehicleData

__all__ = ["ActuatorParams", "linear_actuator_ss", "TvcActuator"]


@dataclass(frozen=True)
class ActuatorParams:
    """Parameters of the TVC actuator (SI units).

    Attributes
    ----------
    wn_radps
        Natural frequency ω [rad/s].
    zeta
        Damping ratio ζ [-].
    position_limit_rad
        Mechanical stop |β| ≤ this [rad] (thesis Table 3.1: 6.5°).
    rate_limit_radps
        Slew-rate limit |β̇| ≤ this [rad/s] (assumption, see vehicle.yaml).
    dt_s
        Integration step of :class:`TvcActuator` = 1/physics rate [s].
    """

    wn_radps: float
    zeta: float
    position_limit_rad: float
    rate_limit_radps: float
    dt_s: float

    def __post_init__(self):
        for name in ("wn_radps", "position_limit_rad", "rate_limit_radps", "dt_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"ActuatorParams.{name} must be finite and > 0, got {value!r}")
        if not (math.isfinite(self.zeta) and self.zeta >= 0.0):
            raise ValueError(f"ActuatorParams.zeta must be finite and >= 0, got {self.zeta!r}")

    @classmethod
    def from_vehicle(cls, data: VehicleData, bandwidth_scale: float = 1.0) -> "ActuatorParams":
        """Actuator parameters from the vehicle data file.

        Parameters
        ----------
        data
            Loaded vehicle data (section ``actuator``).
        bandwidth_scale
            Multiplies the natural frequency: ``1 + δ`` with δ the ``actuator`` deviation
            of the uncertainty set (thesis §2.12.3: 10 % on the TVC dynamics). The
            damping ratio and the limits are unchanged.
        """
        return cls(
            wn_radps=data["actuator.natural_frequency_radps"] * float(bandwidth_scale),
            zeta=data["actuator.damping_ratio"],
            position_limit_rad=data["actuator.position_limit_rad"],
            rate_limit_radps=data["actuator.rate_limit_radps"],
            dt_s=1.0 / data["actuator.physics_rate_hz"],
        )


def linear_actuator_ss(params: ActuatorParams):
    """Continuous-time unlimited actuator, input β_cmd, outputs [β, β̇, β̈].

    Parameters
    ----------
    params
        Actuator parameters (only ``wn_radps`` and ``zeta`` are used).

    Returns
    -------
    A, B, C, D : numpy.ndarray
        Shapes 2×2, 2×1, 3×2, 3×1; state [β, β̇].

    Notes
    -----
    β̈ = ω²(β_cmd − β) − 2ζω β̇, i.e. β/β_cmd = ω²/(s² + 2ζω s + ω²) (thesis §2.12.3 and
    its code, ω = 100 rad/s, ζ = 0.5). β̈ is an output with a direct feed-through, as the
    plant model needs it as an input (tail-wags-dog, thesis §2.7).
    """
    w2 = params.wn_radps ** 2
    c = 2.0 * params.zeta * params.wn_radps
    A = np.array([[0.0, 1.0], [-w2, -c]])
    B = np.array([[0.0], [w2]])
    C = np.array([[1.0, 0.0], [0.0, 1.0], [-w2, -c]])
    D = np.array([[0.0], [0.0], [w2]])
    return A, B, C, D


def zoh_transition(params: ActuatorParams) -> tuple[tuple[float, float], tuple[float, float]]:
    """Φ = e^{A·dt} of the unlimited actuator (:func:`linear_actuator_ss`) in closed form, as
    rows (Φ₁₁, Φ₁₂), (Φ₂₁, Φ₂₂).

    With σ = ζω and ω_d = ω·√(1 − ζ²) (imaginary when ζ > 1, where sin and cos turn into
    sinh and cosh), s(t) = sin(ω_d t)/ω_d (→ t as ω_d → 0, ζ = 1):

        Φ = e^{−σt} [[cos ω_d t + σ s,  s], [−ω² s,  cos ω_d t − σ s]].

    (Any 2×2 matrix exponential: e^{At} = e^{tr(A)t/2}·(cosh(μt)·I + sinh(μt)/μ·(A − tr(A)/2·I)),
    μ² = tr(A)²/4 − det A; here tr A = −2σ, det A = ω², μ = iω_d.) Closed form rather than
    ``scipy.linalg.expm``: the actuator node would import scipy.linalg only for this
    (≈ 0.2 s of its start-up, docs/SIL_SPEED.md); tests/model compares it with expm."""
    w, t = params.wn_radps, params.dt_s
    sigma = params.zeta * w
    wd = cmath.sqrt(complex(w * w - sigma * sigma))
    x = wd * t
    # sin(x)/x for small |x| by its series: exact to rounding below 1e-4 (next term x⁴/120)
    sinc = (cmath.sin(x) / x if abs(x) > 1e-4 else 1.0 - x * x / 6.0) * t
    cos = cmath.cos(x)
    decay = math.exp(-sigma * t)
    p11 = decay * (cos + sigma * sinc)
    p12 = decay * sinc
    p21 = -decay * w * w * sinc
    p22 = decay * (cos - sigma * sinc)
    return (p11.real, p12.real), (p21.real, p22.real)


class TvcActuator:
    """Nonlinear discrete-time TVC actuator stepped at ``params.dt_s``.

    State (β, β̇) [rad, rad/s]; the command β_cmd is held over each step (zero-order hold).

    Limiter law, one step from (β_k, β̇_k) with held command u (applied in this order):

    1. Linear step, exact for the unlimited law β̈ = ω²(u − β) − 2ζωβ̇:
       (β', β̇') = Φ (β_k, β̇_k) + Γ u with Φ = e^{A dt}, Γ = ∫₀^dt e^{Aτ} dτ B — computed
       as (β', β̇') = (u, 0) + Φ (β_k − u, β̇_k), the same since Γ = (I − Φ)(1, 0) (the held
       command is the equilibrium β = u, β̇ = 0), and exact at rest: a nozzle at rest where
       it is commanded stays there to the last bit (Φ: :func:`zoh_transition`).
    2. Rate limit R: if |β̇'| > R then β̇' ← sign(β̇')·R and the position follows the
       limited rate, β' ← β_k + dt·(β̇_k + β̇')/2 (trapezoid). In every case the step is
       then bounded, β' ← β_k + clip(β' − β_k, −R·dt, R·dt) (this acts only when the
       linear path exceeds R inside the step, e.g. the step that leaves the limit).
    3. Position limit P: if β' > P then β' ← P and β̇' ← min(β̇', 0) (likewise at −P with
       max): the nozzle stops at the stop and only leaves it moving away from it.
    4. β_{k+1} = β', β̇_{k+1} = β̇'; the reported acceleration is the law at the new state,
       β̈_{k+1} = ω²(u − β_{k+1}) − 2ζωβ̇_{k+1}, set to 0 when a limit holds it: on the
       rate limit (β̇ = ±R) with β̈ pushing beyond it, or on a stop (β = ±P) with β̈
       pushing into it.

    Unlimited, the samples equal the exact continuous response to the held command (to
    rounding). At a limit the law is first-order accurate in dt at the switching step.

    A non-finite command (NaN, ±inf) is treated as "hold the last finite command" (after
    :meth:`reset`, the command that holds the reset position). The step never raises.
    """

    def __init__(self, params: ActuatorParams, beta0_rad: float = 0.0):
        self.params = params
        dt = params.dt_s
        (self._p11, self._p12), (self._p21, self._p22) = zoh_transition(params)
        self._w2 = params.wn_radps ** 2
        self._c = 2.0 * params.zeta * params.wn_radps
        self._half_dt = 0.5 * dt
        self._pos = params.position_limit_rad
        self._rate = params.rate_limit_radps
        self._max_step = params.rate_limit_radps * dt
        self.reset(beta0_rad)

    def reset(self, beta0_rad: float = 0.0) -> None:
        """Put the nozzle at rest at ``beta0_rad`` (clamped to the stops), commanded there.

        Raises
        ------
        ValueError
            If ``beta0_rad`` is not finite.
        """
        if not math.isfinite(beta0_rad):
            raise ValueError(f"beta0_rad must be finite, got {beta0_rad!r}")
        b = min(max(float(beta0_rad), -self._pos), self._pos)
        self.beta_rad = b
        self.beta_dot_radps = 0.0
        self.beta_ddot_radps2 = 0.0
        self.command_rad = b

    @property
    def state(self) -> tuple[float, float, float]:
        """Current (β [rad], β̇ [rad/s], β̈ [rad/s²])."""
        return self.beta_rad, self.beta_dot_radps, self.beta_ddot_radps2

    def step(self, beta_cmd_rad: float) -> tuple[float, float, float]:
        """Advance one step ``dt_s`` with the command held; return (β, β̇, β̈) at its end."""
        u = float(beta_cmd_rad)
        if math.isfinite(u):
            self.command_rad = u
        else:
            u = self.command_rad
        b0, r0 = self.beta_rad, self.beta_dot_radps
        e = b0 - u
        b = u + self._p11 * e + self._p12 * r0
        r = self._p21 * e + self._p22 * r0
        rate, pos = self._rate, self._pos
        if r > rate:
            r = rate
            b = b0 + self._half_dt * (r0 + r)
        elif r < -rate:
            r = -rate
            b = b0 + self._half_dt * (r0 + r)
        max_step = self._max_step
        if b - b0 > max_step:
            b = b0 + max_step
        elif b - b0 < -max_step:
            b = b0 - max_step
        if b > pos:
            b = pos
            r = min(r, 0.0)
        elif b < -pos:
            b = -pos
            r = max(r, 0.0)
        a = self._w2 * (u - b) - self._c * r
        if (a > 0.0 and (r >= rate or b >= pos)) or (a < 0.0 and (r <= -rate or b <= -pos)):
            a = 0.0
        self.beta_rad, self.beta_dot_radps, self.beta_ddot_radps2 = b, r, a
        return b, r, a

    def run(self, commands) -> tuple[list[float], list[float], list[float], list[float]]:
        """:meth:`step` once per command of ``commands``; return the lists of β, β̇, β̈ at
        the step ends and of the command held over each step (:attr:`command_rad` after it).
        The same arithmetic as :meth:`step`, in one loop (the actuator node's frame)."""
        betas, rates, accels, helds = self.run_tuples(commands)
        return list(betas), list(rates), list(accels), list(helds)

    def run_tuples(self, commands) -> tuple[tuple[float, ...], tuple[float, ...],
                                            tuple[float, ...], tuple[float, ...]]:
        """:meth:`run` with tuples in place of the lists (the actuator node's frame)."""
        p11, p12, p21, p22 = self._p11, self._p12, self._p21, self._p22
        rate, pos, half_dt, max_step = self._rate, self._pos, self._half_dt, self._max_step
        w2, c = self._w2, self._c
        isfinite = math.isfinite
        b0, r0, a, held = self.beta_rad, self.beta_dot_radps, self.beta_ddot_radps2, \
            self.command_rad
        neg_rate, neg_pos, neg_step = -rate, -pos, -max_step    # the negated limits, once
        rows = []
        append = rows.append
        last = rows                          # no command yet (a held command repeats as the
        for cmd in commands:                 # same object: converted and checked once)
            if cmd is not last:
                last = cmd
                u = float(cmd)
                if isfinite(u):
                    held = u
                else:
                    u = held
            e = b0 - u
            b = u + p11 * e + p12 * r0
            r = p21 * e + p22 * r0
            if r > rate:
                r = rate
                b = b0 + half_dt * (r0 + r)
            elif r < neg_rate:
                r = neg_rate
                b = b0 + half_dt * (r0 + r)
            d = b - b0
            if d > max_step:
                b = b0 + max_step
            elif d < neg_step:
                b = b0 - max_step
            if b > pos:
                b = pos
                r = min(r, 0.0)
            elif b < neg_pos:
                b = neg_pos
                r = max(r, 0.0)
            a = w2 * (u - b) - c * r
            if (a > 0.0 and (r >= rate or b >= pos)) or (a < 0.0 and (r <= neg_rate
                                                                  or b <= neg_pos)):
                a = 0.0
            append((b, r, a, held))
            b0, r0 = b, r
        self.beta_rad, self.beta_dot_radps, self.beta_ddot_radps2 = b0, r0, a
        self.command_rad = held
        if not rows:
            return (), (), (), ()
        betas, rates, accels, helds = zip(*rows)
        return betas, rates, accels, helds

    def advance(self, beta_cmd_rad, n_steps: int):
        """Advance ``n_steps`` steps; return arrays (β, β̇, β̈), one entry per step end.

        Parameters
        ----------
        beta_cmd_rad
            A command held for all steps, or a sequence of ``n_steps`` commands (one per
            step, e.g. a delayed command that changes inside a frame).
        n_steps
            Number of steps of ``dt_s``.
        """
        n = int(n_steps)
        if n < 0:
            raise ValueError(f"n_steps must be >= 0, got {n_steps!r}")
        if np.ndim(beta_cmd_rad) == 0:
            commands = [float(beta_cmd_rad)] * n
        else:
            commands = [float(c) for c in np.ravel(beta_cmd_rad)]
            if len(commands) != n:
                raise ValueError(f"{len(commands)} commands given for {n} steps")
        out = np.empty((3, n))
        for k, u in enumerate(commands):
            out[:, k] = self.step(u)
        return out[0], out[1], out[2]
