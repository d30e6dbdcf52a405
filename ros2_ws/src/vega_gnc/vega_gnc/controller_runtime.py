"""The gain-scheduled TVC controller as it runs on board: one step per INS measurement.

Plain Python, no ROS: the ``tvc_controller`` node and the offline verification run this same
code. Per step (at the controller rate, thesis §4.3.2 "affine interpolation"):

1. validate the measurement (finite fields, ``valid`` flag, stamp strictly later than the
   previous one and not older than ``max_age_s`` at the time of use);
2. schedule on the measured velocity: the discrete controller matrices are interpolated
   linearly in velocity between grid points (clamped at the grid ends, flagged);
3. ``u = Cd x + Dd y``, ``x ← Ad x + Bd y`` with ``y = sign · measurements`` in the table's
   input order (sign −1: the controller input is reference − measurement, references 0);
4. limit the command to the actuator range (flagged).

Defined safe behaviour (never an exception in the loop):

* an invalid or stale measurement → the last command is held and the controller state is
  frozen (``STATUS_HOLD_LAST``);
* no valid measurement yet, or invalid for longer than ``hold_limit_s`` → command 0 and the
  controller state reset (``STATUS_SAFE_ZERO``); a later valid measurement restarts it;
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

from vega_gnc.controller_table import ControllerTable

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
    """

    limit_rad: float = math.radians(6.5)
    max_age_s: float = 0.032
    hold_limit_s: float = 0.2


class ControllerRuntime:
    """Scheduled discrete LPV controller with input validation (see module docstring)."""

    def __init__(self, table: ControllerTable, limits: RuntimeLimits = RuntimeLimits(),
                 rate_mps2: float | None = None):
        self.table = table
        self.limits = limits
        self._sign = float(table.measurement_sign)
        self._getters = tuple(_FIELDS[name] for name in table.input_names)
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
        self.reset()

    def reset(self) -> None:
        """Zero the controller state; the next valid measurement starts it."""
        self._xy[:] = 0.0
        self._last_stamp = -math.inf
        self._last_valid_stamp = None
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

    def _step(self, m: Measurement, now_s: float) -> Command:
        values = [getattr(m, name) for name in self._getters]
        v = m.velocity_mps
        ok = (bool(m.valid) and all(math.isfinite(x) for x in values) and math.isfinite(v)
              and math.isfinite(m.stamp_s) and m.stamp_s > self._last_stamp
              and now_s - m.stamp_s <= self.limits.max_age_s)
        if math.isfinite(m.stamp_s) and m.stamp_s > self._last_stamp:
            self._last_stamp = m.stamp_s
        if not ok:
            held = self._last_valid_stamp is not None and (
                now_s - self._last_valid_stamp <= self.limits.hold_limit_s)
            if held:
                return Command(self._last_command, v if math.isfinite(v) else float("nan"),
                               STATUS_HOLD_LAST)
            self.reset()
            return Command(0.0, v if math.isfinite(v) else float("nan"), STATUS_SAFE_ZERO)
        S, v_sched, status = self._schedule(v)
        n = self._n
        self._xy[n:] = values
        self._xy[n:] *= self._sign
        out = S @ self._xy
        u = float(out[n])
        self._xy[:n] = out[:n]
        lim = self.limits.limit_rad
        if abs(u) > lim:
            u = math.copysign(lim, u)
            status = max(status, STATUS_LIMITED, key=_SEVERITY.__getitem__)
        self._last_valid_stamp = m.stamp_s
        self._last_command = u
        return Command(u, v_sched, status)
