"""The gain-scheduled TVC controller as it runs on board: one step per INS measurement.

Plain Python, no ROS: the ``tvc_controller`` node and the offline verification run this same
code. Per step (at the controller rate, thesis §4.3.2 "affine interpolation"):

1. validate the measurement: ``valid`` flag; every field finite and within its plausibility
   bound (:class:`RuntimeLimits`: values no flying launcher can have, so that a corrupted
   value can neither overflow the controller state nor pin the command); stamp strictly later
   than the previous one, not in the future and not older than ``max_age_s`` at the time of
   use (times compared in whole microseconds, so that a limit on the millisecond grid holds
   exactly);
2. schedule on the measured velocity: the discrete controller matrices are interpolated
   linearly in velocity between grid points (clamped at the grid ends, flagged);
3. ``u = Cd x + Dd y + β_ff(t)``, ``x ← Ad x + Bd y`` with
   ``y = sign · (measurements − references(t))`` in the table's input order (sign −1: the
   controller input is reference − measurement); references and feed-forward β_ff come from the
   guidance reference (:mod:`vega_gnc.guidance_reference`, at the sample time), or are 0 when
   none is flown;
4. check that the new state and the command are finite; limit the command to the actuator
   range (flagged).

Defined safe behaviour (never an exception in the loop):

* an invalid, implausible, stale or future-stamped measurement → the last command is held and
  the controller state is frozen (``STATUS_HOLD_LAST``);
* no valid measurement yet, or none for longer than ``hold_limit_s`` → command 0 and the
  controller state reset (``STATUS_SAFE_ZERO``); a later valid measurement restarts it. The
  hold runs on the receive side (from the time the last valid measurement was *used*), so no
  stamp can extend it;
* a non-finite state or command (only possible with a table whose gains overflow the state) →
  the state is reset, command 0 (``STATUS_SAFE_ZERO``);
* velocity outside the grid → matrices clamped to the end point (``STATUS_VELOCITY_CLAMPED``);
* command beyond ±``limit_rad`` → saturated (``STATUS_LIMITED``).
Status values are the constants of ``vega_msgs/TvcCommand`` (taken from the message class);
when several apply the most severe wins (SAFE_ZERO > HOLD_LAST > LIMITED > VELOCITY_CLAMPED >
OK).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from vega_msgs.msg import TvcCommand

from vega_gnc.controller_table import MEASUREMENT_NAMES, ControllerTable
from vega_gnc.guidance_reference import GuidanceReference

__all__ = ["STATUS_OK", "STATUS_HOLD_LAST", "STATUS_VELOCITY_CLAMPED", "STATUS_SAFE_ZERO",
           "STATUS_LIMITED", "Measurement", "Command", "RuntimeLimits", "ControllerRuntime"]

# The status values are declared once, in vega_msgs/msg/TvcCommand.msg; these are its constants.
STATUS_OK = TvcCommand.STATUS_OK
STATUS_HOLD_LAST = TvcCommand.STATUS_HOLD_LAST
STATUS_VELOCITY_CLAMPED = TvcCommand.STATUS_VELOCITY_CLAMPED
STATUS_SAFE_ZERO = TvcCommand.STATUS_SAFE_ZERO
STATUS_LIMITED = TvcCommand.STATUS_LIMITED
_SEVERITY = {STATUS_OK: 0, STATUS_VELOCITY_CLAMPED: 1, STATUS_LIMITED: 2,
             STATUS_HOLD_LAST: 3, STATUS_SAFE_ZERO: 4}
_FIELDS = {"theta_ins_rad": "pitch_rad", "theta_dot_ins_radps": "pitch_rate_radps",
           "z_ins_m": "drift_m", "z_dot_ins_mps": "drift_rate_mps"}


class Measurement(NamedTuple):
    """One INS measurement as the controller receives it (SI units)."""

    stamp_s: float
    pitch_rad: float
    pitch_rate_radps: float
    drift_m: float
    drift_rate_mps: float
    velocity_mps: float
    valid: bool = True


class Command(NamedTuple):
    """One controller output."""

    deflection_cmd_rad: float
    scheduling_velocity_mps: float
    status: int


@dataclass(frozen=True)
class RuntimeLimits:
    """Safety parameters of the runtime.

    limit_rad: actuator position limit (thesis Table 3.1, 6.5°); max_age_s: a measurement
    older than this when used is stale (assumption: 2 INS periods + the 12 ms sensor latency);
    hold_limit_s: how long a held command is trusted before going to zero (assumption: 0.2 s,
    ≈ 1/5 of the aerodynamic divergence time constant at max-Q).

    Plausibility bounds of the measurement (assumption: values no flying launcher can have; a
    measurement beyond one is a sensor or transport fault and is not used):
    max_abs_pitch_rad = π (an attitude perturbation beyond ±180° has no meaning);
    max_abs_pitch_rate_radps = 10 rad/s (≈ 570°/s; VEGA's attitude dynamics are below 1 rad/s);
    max_abs_drift_m = 1e5 m (100 km: more than the whole first-stage ascent's downrange);
    max_abs_drift_rate_mps = 1e4 m/s and max_velocity_mps = 1e4 m/s (more than 5× the
    first-stage burn-out velocity, ≈ 1.9 km/s, docs/TRAJECTORY.md; a small negative measured
    velocity at lift-off is INS noise, not a fault).
    """

    limit_rad: float = math.radians(6.5)
    max_age_s: float = 0.032
    hold_limit_s: float = 0.2
    max_abs_pitch_rad: float = math.pi
    max_abs_pitch_rate_radps: float = 10.0
    max_abs_drift_m: float = 1e5
    max_abs_drift_rate_mps: float = 1e4
    max_velocity_mps: float = 1e4


def _us(t_s: float) -> int:
    """``t_s`` in whole microseconds (stamps and limits are on the millisecond grid)."""
    return round(t_s * 1e6)


class ControllerRuntime:
    """Scheduled discrete LPV controller with input validation (see module docstring)."""

    def __init__(self, table: ControllerTable, limits: RuntimeLimits = RuntimeLimits(),
                 rate_mps2: float | None = None, reference: GuidanceReference | None = None):
        self.table = table
        self.limits = limits
        self.reference = reference
        # columns of the reference's [references..., feed-forward] rows, in the input order
        self._ref_cols = [MEASUREMENT_NAMES.index(name) for name in table.input_names]
        self._sign = float(table.measurement_sign)
        self._getters = tuple(_FIELDS[name] for name in table.input_names)
        bounds = {"pitch_rad": limits.max_abs_pitch_rad,
                  "pitch_rate_radps": limits.max_abs_pitch_rate_radps,
                  "drift_m": limits.max_abs_drift_m,
                  "drift_rate_mps": limits.max_abs_drift_rate_mps}
        self._bounds = tuple(bounds[name] for name in self._getters)
        self._max_age_us = _us(limits.max_age_s)
        self._hold_us = _us(limits.hold_limit_s)
        n, ny = table.n_states, len(table.input_names)
        # One stacked matrix per grid point, S = [[Ad, Bd], [Cd, Dd]], and its increments to
        # the next point, so that a step is one axpy and one mat-vec product.
        rate = None if table.rate_grid_mps2 is None else (
            table.rate_grid_mps2[1] if rate_mps2 is None else rate_mps2)
        stacks = []
        for i, _ in enumerate(table.grid_v_mps):
            if table.rate_grid_mps2 is None:
                Ad, Bd, Cd, Dd = table.Ad[i], table.Bd[i], table.Cd[i], table.Dd[i]
            else:
                _, _, _, s = table.weights(float(table.grid_v_mps[i]), rate)
                Ad, Bd, Cd, Dd = ((1 - s) * m[i][0] + s * m[i][1]
                                  for m in (table.Ad, table.Bd, table.Cd, table.Dd))
            stacks.append(np.block([[Ad, Bd], [Cd, Dd]]))
        self._S = np.array(stacks)
        self._dS = np.diff(self._S, axis=0)
        self._n, self._ny = n, ny
        self._xy = np.zeros(n + ny)
        self._work = np.empty_like(self._S[0])
        self._last_stamp_us = None      # newest stamp seen: kept across resets, so that a
        self.reset()                    # repeated or older message is never used

    def reset(self) -> None:
        """Zero the controller state; the next valid measurement starts it."""
        self._xy[:] = 0.0
        self._last_valid_us = None      # receive time of the last measurement used
        self._last_command = 0.0

    @property
    def state(self) -> np.ndarray:
        """Copy of the controller state."""
        return self._xy[:self._n].copy()

    def _schedule(self, v: float) -> tuple[np.ndarray, float, int]:
        """Controller matrices at velocity ``v``, the velocity they belong to (``v`` clamped
        to the grid) and the scheduling status."""
        g = self.table.grid_v_mps
        status = STATUS_OK
        v_sched = min(max(v, float(g[0])), float(g[-1]))
        if v_sched != v:
            status = STATUS_VELOCITY_CLAMPED
        i, w, _, _ = self.table.weights(v_sched)
        np.multiply(self._dS[i], w, out=self._work)
        self._work += self._S[i]
        return self._work, v_sched, status

    def step(self, m: Measurement, now_s: float | None = None) -> Command:
        """Advance one controller period with measurement ``m`` (used at time ``now_s``,
        default ``m.stamp_s``). Never raises."""
        try:
            return self._step(m, m.stamp_s if now_s is None else now_s)
        except Exception:  # noqa: BLE001 - the loop must never raise: fail safe
            self.reset()
            return Command(0.0, float("nan"), STATUS_SAFE_ZERO)

    def _plausible(self, values, v: float) -> bool:
        """Every used field and the velocity finite and within their bounds."""
        for x, bound in zip(values, self._bounds):
            if not abs(x) <= bound:         # False for NaN too
                return False
        return abs(v) <= self.limits.max_velocity_mps

    def _step(self, m: Measurement, now_s: float) -> Command:
        now_us = _us(now_s)                 # ValueError/OverflowError for a non-finite now_s
        values = [getattr(m, name) for name in self._getters]
        v = m.velocity_mps
        stamp_us = _us(m.stamp_s) if math.isfinite(m.stamp_s) else None
        newer = stamp_us is not None and (self._last_stamp_us is None
                                          or stamp_us > self._last_stamp_us)
        ok = (bool(m.valid) and newer and 0 <= now_us - stamp_us <= self._max_age_us
              and self._plausible(values, v))
        if newer and stamp_us <= now_us:
            self._last_stamp_us = stamp_us
        v_report = v if math.isfinite(v) else float("nan")
        if not ok:
            return self._hold_or_zero(now_us, v_report)
        S, v_sched, status = self._schedule(v)
        n = self._n
        self._xy[n:] = values
        ref = None
        if self.reference is not None:
            ref = self.reference.at(m.stamp_s)
            self._xy[n:] -= ref[self._ref_cols]
        self._xy[n:] *= self._sign
        out = S @ self._xy
        u = float(out[n])
        if ref is not None:
            u += float(ref[-1])             # the feed-forward of the reference
        if not (math.isfinite(u) and np.isfinite(out).all()):
            self.reset()                    # a table whose gains overflow: never emit it
            return Command(0.0, v_sched, STATUS_SAFE_ZERO)
        self._xy[:n] = out[:n]
        lim = self.limits.limit_rad
        if abs(u) > lim:
            u = math.copysign(lim, u)
            status = max(status, STATUS_LIMITED, key=_SEVERITY.__getitem__)
        self._last_valid_us = now_us
        self._last_command = u
        return Command(u, v_sched, status)

    def _hold_or_zero(self, now_us: int, v_report: float) -> Command:
        """The last command while the hold limit allows (receive side), else zero and reset."""
        if self._last_valid_us is not None and now_us - self._last_valid_us <= self._hold_us:
            return Command(self._last_command, v_report, STATUS_HOLD_LAST)
        self.reset()
        return Command(0.0, v_report, STATUS_SAFE_ZERO)
