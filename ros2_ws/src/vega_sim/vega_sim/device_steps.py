"""The INS and actuator of the closed loop as step functions (one class per node).

Plain Python, no ROS: the in-process simulation (:mod:`vega_sim.closed_loop`) and the SIL
nodes (:mod:`vega_plant.nodes`) call these same classes, so both produce the same numbers.
Each class takes and returns plain values whose fields are those of the ``vega_msgs`` message
it will publish, with stamps as integer milliseconds (:mod:`vega_bus.wire` converts them to
messages). The controller's step class, on the flight side, is
:class:`vega_gnc.controller_step.ControllerStep`:

* :class:`InsStep` — samples the truth every frame (100 Hz) with
  :class:`vega_model.ins.InsSensor` (seeded noise); the measurement is stamped sample +
  sensor latency (12 ms). → :class:`vega_bus.records.InsOut` (``InsMeasurement``)
* ControllerStep (:mod:`vega_gnc.controller_step`) — every measurement whose sample time is
  a multiple of the controller period (20 ms) goes through
  :class:`vega_gnc.controller_runtime.ControllerRuntime` exactly as flown, at its arrival; the
  command is stamped arrival + computing latency (12 ms).
  → :class:`vega_bus.records.CommandOut` (``TvcCommand``)
* :class:`ActuatorStep` — applies each command at its stamp + actuator latency (15 ms), holds
  it until the next one, and integrates :class:`vega_model.actuator.TvcActuator` (limits
  included) at the physics rate one frame at a time. → :class:`vega_bus.records.ActuatorOut`
  (``ActuatorState``)

The records live in :mod:`vega_bus.records` (``ActuatorOut`` is re-exported here).
"""

from __future__ import annotations

import bisect
import math

from vega_bus.records import ActuatorOut, InsOut, TruthOut
from vega_bus.timing import LoopTiming, check_ms

from vega_model.actuator import ActuatorParams, TvcActuator
from vega_model.ins import InsParams, InsSample, InsSensor
from vega_model.parameters import ModelParameters

__all__ = ["ActuatorOut", "InsStep", "ActuatorStep"]


def _all_finite(values, extra: float) -> bool:
    """``all(math.isfinite(x) for x in (*values, extra))``, with a fast path: a finite sum
    of the values proves them all finite; otherwise each is checked."""
    if math.isfinite(sum(values, extra)):
        return True
    return all(math.isfinite(x) for x in values) and math.isfinite(extra)


class InsStep:
    """INS sensor node: one measurement per frame.

    Parameters
    ----------
    params
        INS parameters (noise levels; rate and latency must match ``timing``).
    timing
        Loop timing (frame = INS period, sensor latency).
    seed
        Noise seed (:class:`vega_model.ins.InsSensor`).
    noise
        False: exact kinematics.
    """

    def __init__(self, params: InsParams, timing: LoopTiming, seed: int, noise: bool = True):
        check_ms(1.0 / params.rate_hz, timing.frame_ms, "INS period")
        check_ms(params.latency_s, timing.sensor_latency_ms, "INS latency")
        self._sensor = InsSensor(params, seed=seed, noise=noise)
        self._latency_ms = timing.sensor_latency_ms
        self._seq = 0

    def sample(self, truth: TruthOut, model_params: ModelParameters) -> InsOut:
        """Measure the truth of one frame.

        Parameters
        ----------
        truth
            The plant's truth at the sample time.
        model_params
            Model parameters at the sample time (INS lever arm and mode shapes).
        """
        state = truth.state
        v = truth.velocity_mps
        # all finite: a finite sum proves it (a NaN or ±inf anywhere makes the sum non-finite);
        # a non-finite sum (or an overflow) is checked value by value
        if _all_finite(state, v):
            s = self._sensor.measure(state, model_params, v)
        else:                                        # a diverged truth: no measurement
            s = InsSample(*(math.nan,) * 5)
        valid = _all_finite(s, 0.0)                  # never a non-finite sample marked valid
        out = InsOut(truth.stamp_ms + self._latency_ms, truth.stamp_ms, self._seq,
                     s.theta_rad, s.theta_dot_radps, s.z_m, s.z_dot_mps, s.velocity_mps, valid)
        self._seq += 1
        return out


class ActuatorStep:
    """TVC actuator node: delayed, held commands and the limited servo at the physics rate.

    Parameters
    ----------
    params
        Actuator parameters (``dt_s`` must be the physics step).
    timing
        Loop timing (physics step, frame, actuator latency).
    t_start_ms
        Time of the first frame.
    beta0_rad
        Initial nozzle angle, at rest and commanded there until the first command applies.
    """

    def __init__(self, params: ActuatorParams, timing: LoopTiming, t_start_ms: int,
                 beta0_rad: float = 0.0):
        check_ms(params.dt_s, timing.physics_dt_ms, "actuator step")
        self._act = TvcActuator(params, beta0_rad)
        self._dt_ms = timing.physics_dt_ms
        self._steps = timing.steps_per_frame
        self._latency_ms = timing.actuator_latency_ms
        self._t_ms = int(t_start_ms)
        self._pending: list[tuple[int, int, float]] = []
        self._command = self._act.command_rad
        self._seq = 0

    @property
    def t_ms(self) -> int:
        """Start of the next frame [ms]."""
        return self._t_ms

    def receive(self, cmd) -> None:
        """Queue a command; it applies from ``cmd.stamp_ms`` + actuator latency.

        ``cmd``: a :class:`vega_bus.records.CommandOut` or anything with its
        ``stamp_ms``, ``seq`` and ``deflection_cmd_rad`` fields.
        """
        bisect.insort(self._pending, (cmd.stamp_ms + self._latency_ms, cmd.seq,
                                      cmd.deflection_cmd_rad))

    def advance(self, t_ms: int) -> ActuatorOut:
        """Integrate the frame [t_ms, t_ms + frame) and return its samples.

        Raises
        ------
        ValueError
            If ``t_ms`` is not the start of the next frame (lockstep violated).
        """
        if t_ms != self._t_ms:
            raise ValueError(f"actuator frame at {t_ms} ms, expected {self._t_ms} ms")
        pending, dt, steps = self._pending, self._dt_ms, self._steps
        command = self._command
        if pending and pending[0][0] <= t_ms + (steps - 1) * dt:   # a command applies
            commands = []
            for k in range(steps):
                while pending and pending[0][0] <= t_ms + k * dt:
                    command = pending.pop(0)[2]
                commands.append(command)
        else:                                                       # the held one only
            commands = [command] * steps
        self._command = command
        # (β, β̇, β̈) and the finite command in force (a NaN/inf command holds the last)
        beta, rate, accel, held = self._act.run_tuples(commands)
        self._t_ms = t_ms + self._steps * dt
        out = ActuatorOut(self._t_ms, self._seq, beta, rate, accel, held, dt / 1000.0)
        self._seq += 1
        return out
