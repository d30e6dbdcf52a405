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
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from vega_msgs.msg import TvcCommand

from vega_gnc.controller_table import MEASUREMENT_NAMES, ControllerTable
from vega_gnc.guidance_reference import GuidanceReference

__all__ = ["STATUS_OK", "STATUS_HOLD_LAST", "STATUS_VELOCITY_CLAMPED", "STATUS_SAFE_ZERO",
           "STATUS_LIMITED", "Measurement", "Command", "RuntimeLimits", "ControllerRuntime",
           "ControllerBatch"]

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


class ControllerBatch:
    """N independent copies of :class:`ControllerRuntime`, stepped at once on arrays.

    The runtime's step (module docstring: validation, hold and safe zero, scheduling, update,
    limit) written element-wise over a leading sample axis, for the batched flight engine
    (``vega_sim.batch``). The matrices, bounds and limits are those of a
    :class:`ControllerRuntime` built from the same arguments (its ``_S``, ``_dS``, bounds and
    reference), and every operation is the runtime's, element by element: the same numbers
    for each sample as its own runtime fed the same measurements (tests/gnc/ and
    tests/sim/test_batch.py compare them bit for bit, fault paths included).

    One difference of form: the runtime never raises because it catches any exception of a
    step; here the only one it can meet, a non-finite ``now_s``, is handled as the runtime's
    handler does (state reset, command 0, velocity NaN, ``STATUS_SAFE_ZERO``).

    Parameters
    ----------
    n
        Number of samples.
    table, limits, rate_mps2
        As :class:`ControllerRuntime` (the same for every sample).
    reference
        As :class:`ControllerRuntime`: one reference for every sample, or a sequence of n
        references, sample i flying ``reference[i]`` (all given or none: None for all).
        References on one time grid are read together (the same operations as
        :meth:`GuidanceReference.at`, row by row); others one by one.
    """

    def __init__(self, n: int, table: ControllerTable, limits: RuntimeLimits = RuntimeLimits(),
                 rate_mps2: float | None = None,
                 reference: GuidanceReference | Sequence[GuidanceReference] | None = None):
        self.n = int(n)
        many = None
        if reference is not None and not isinstance(reference, GuidanceReference):
            many = list(reference)
            if len(many) != self.n or not all(isinstance(r, GuidanceReference) for r in many):
                raise ValueError(f"ControllerBatch: reference must be one GuidanceReference "
                                 f"or {self.n} of them")
            reference = many[0]
        rt = ControllerRuntime(table, limits, rate_mps2, reference)
        self.runtime = rt
        self._many = None
        if many is not None and any(r is not many[0] for r in many):
            t = many[0].t_s
            shared = all(r.t_s.shape == t.shape and np.array_equal(r.t_s, t) for r in many)
            self._many = many
            self._index = np.arange(self.n)
            self._stacks = (np.stack([r._stack for r in many]),
                            np.stack([r._dstack for r in many])) if shared else None
        fields = ("pitch_rad", "pitch_rate_radps", "drift_m", "drift_rate_mps")
        self._cols = np.array([fields.index(name) for name in rt._getters])
        self._bounds = np.array(rt._bounds, dtype=float)
        self._ref_cols = np.array(rt._ref_cols)
        self._grid = np.asarray(table.grid_v_mps, dtype=float)
        self._xy = np.zeros((self.n, rt._n + rt._ny))
        self._last_stamp_us = np.zeros(self.n, dtype=np.int64)
        self._has_stamp = np.zeros(self.n, dtype=bool)
        self._last_valid_us = np.zeros(self.n, dtype=np.int64)
        self._has_valid = np.zeros(self.n, dtype=bool)
        self._last_command = np.zeros(self.n)

    def _reset(self, mask: np.ndarray) -> None:
        """:meth:`ControllerRuntime.reset` of the samples in ``mask``."""
        self._xy[mask] = 0.0
        self._has_valid[mask] = False
        self._last_command[mask] = 0.0

    def _weights(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`ControllerTable.weights` (i, w) of each velocity (already on the grid)."""
        g = self._grid
        i = np.searchsorted(g, v, side="right") - 1
        low, high = v <= g[0], v >= g[-1]
        i = np.where(low, 0, np.where(high, g.size - 2, i))
        inner = ~(low | high)
        w = np.where(low, 0.0, 1.0)
        j = i[inner]
        w[inner] = (v[inner] - g[j]) / (g[j + 1] - g[j])
        return i, w

    def step(self, stamp_s: np.ndarray, measured: np.ndarray, velocity_mps: np.ndarray,
             valid: np.ndarray, now_s: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One controller period of every sample (:meth:`ControllerRuntime.step`).

        Parameters
        ----------
        stamp_s, now_s
            Sample time of each measurement and the time it is used [s] (N,).
        measured
            (N, 4): pitch [rad], pitch rate [rad/s], drift [m], drift rate [m/s]
            (the fields of :class:`Measurement`).
        velocity_mps, valid
            Measured velocity [m/s] and valid flag (N,).

        Returns
        -------
        deflection_cmd_rad, scheduling_velocity_mps, status
            Arrays (N,) of the fields of :class:`Command`.
        """
        rt, lim = self.runtime, self.runtime.limits
        stamp_s = np.asarray(stamp_s, dtype=float)
        now_s = np.asarray(now_s, dtype=float)
        v = np.asarray(velocity_mps, dtype=float)
        values = np.asarray(measured, dtype=float)[:, self._cols]
        u = np.zeros(self.n)
        status = np.full(self.n, STATUS_SAFE_ZERO, dtype=np.int64)
        v_out = np.where(np.isfinite(v), v, np.nan)
        # a non-finite now_s: the runtime's exception handler (reset, 0, NaN, SAFE_ZERO)
        now_ok = np.isfinite(now_s)
        all_now = bool(now_ok.all())
        if not all_now:
            self._reset(~now_ok)
            v_out[~now_ok] = np.nan
            now_s = np.where(now_ok, now_s, 0.0)
        now_us = np.rint(now_s * 1e6).astype(np.int64)        # _us: round half to even
        stamp_ok = np.isfinite(stamp_s)
        stamp_us = np.rint(np.where(stamp_ok, stamp_s, 0.0) * 1e6).astype(np.int64)
        newer = stamp_ok & (~self._has_stamp | (stamp_us > self._last_stamp_us))
        age = now_us - stamp_us
        ok = np.asarray(valid, dtype=bool) & newer & (age >= 0) & (age <= rt._max_age_us)
        ok &= np.abs(values).__le__(self._bounds).all(axis=1)   # _plausible (False for NaN)
        ok &= np.abs(v) <= lim.max_velocity_mps
        seen = newer & (age >= 0)
        if not all_now:
            ok &= now_ok
            seen &= now_ok
        self._last_stamp_us = np.where(seen, stamp_us, self._last_stamp_us)
        self._has_stamp |= seen
        if ok.all():                                  # every measurement used
            self._update(slice(None), stamp_s, values, v, now_us, u, v_out, status)
            return u, v_out, status
        # _hold_or_zero
        hold = (~ok & now_ok & self._has_valid
                & (now_us - self._last_valid_us <= rt._hold_us))
        u[hold] = self._last_command[hold]
        status[hold] = STATUS_HOLD_LAST
        self._reset(~ok & now_ok & ~hold)
        k = np.flatnonzero(ok)
        if k.size:
            self._update(k, stamp_s[k], values[k], v[k], now_us[k], u, v_out, status)
        return u, v_out, status

    def _reference(self, stamp_s: np.ndarray, k) -> np.ndarray:
        """The guidance reference's row (:meth:`GuidanceReference.at`) at each sample time of
        the samples ``k`` (indices or a slice)."""
        if self._many is not None:
            return self._references(stamp_s, k)
        at = self.runtime.reference.at
        if (stamp_s == stamp_s[0]).all():             # one sample time (a batch's frame)
            return at(float(stamp_s[0]))[None, :]
        times, where = np.unique(stamp_s, return_inverse=True)
        return np.array([at(float(t)) for t in times])[where.ravel()]

    def _references(self, stamp_s: np.ndarray, k) -> np.ndarray:
        """:meth:`_reference` with one reference per sample."""
        idx = self._index[k]
        if self._stacks is not None and (stamp_s == stamp_s[0]).all():
            ref = self._many[0]                       # the shared grid: at()'s index, factor
            t, ts = ref.t_s, float(stamp_s[0])
            i = int(np.searchsorted(t, ts, side="right")) - 1
            stack, dstack = self._stacks
            if i < 0:
                return stack[idx, 0].copy()
            if i >= t.size - 1:
                return stack[idx, -1].copy()
            return stack[idx, i] + ((ts - t[i]) / ref._dt[i]) * dstack[idx, i]
        return np.array([self._many[j].at(float(ts)) for j, ts in zip(idx, stamp_s)])

    def _update(self, k, stamp_s, values, v, now_us, u, v_out, status) -> None:
        """The scheduled update of the samples ``k`` (indices or a slice) whose measurement
        is used (the part of :meth:`ControllerRuntime._step` after the checks), into ``u``,
        ``v_out``, ``status``."""
        rt, g = self.runtime, self._grid
        n = rt._n
        # _schedule: min(max(v, g0), g1) as Python's max and min choose
        low = np.where(g[0] > v, g[0], v)
        v_sched = np.where(g[-1] < low, g[-1], low)
        st = np.where(v_sched != v, STATUS_VELOCITY_CLAMPED, STATUS_OK)
        i, w = self._weights(v_sched)
        S = rt._dS[i] * w[:, None, None]
        S += rt._S[i]
        xy = self._xy[k]
        xy[:, n:] = values
        ff = None
        if rt.reference is not None:
            refs = self._reference(stamp_s, k)
            xy[:, n:] -= refs[:, self._ref_cols]
            ff = refs[:, -1]
        xy[:, n:] *= rt._sign
        out = np.matmul(S, xy[:, :, None])[:, :, 0]
        cmd = out[:, n].copy()
        if ff is not None:
            cmd += ff                             # the feed-forward of the reference
        bad = ~(np.isfinite(cmd) & np.isfinite(out).all(axis=1))
        xy[:, :n] = out[:, :n]
        self._xy[k] = xy
        lim = rt.limits.limit_rad
        over = np.abs(cmd) > lim
        if over.any():
            cmd[over] = np.copysign(lim, cmd[over])
            st[over] = STATUS_LIMITED             # more severe than OK and VELOCITY_CLAMPED
        any_bad = bool(bad.any())
        if any_bad:
            cmd[bad], st[bad] = 0.0, STATUS_SAFE_ZERO
        u[k], v_out[k], status[k] = cmd, v_sched, st
        if not any_bad:
            self._last_valid_us[k] = now_us
            self._has_valid[k] = True
            self._last_command[k] = cmd
            return
        kk = np.arange(self.n)[k]
        good = kk[~bad]
        self._last_valid_us[good] = now_us[~bad]
        self._has_valid[good] = True
        self._last_command[good] = cmd[~bad]
        self._reset(kk[bad])
