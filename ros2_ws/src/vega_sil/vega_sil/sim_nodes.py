"""The INS, controller and actuator of the closed loop as step functions (one class per node).

Plain Python, no ROS: the in-process simulation (:mod:`vega_sil.closed_loop`) and the SIL
nodes call these same classes, so both produce the same numbers. Each class takes and returns
plain values whose fields are those of the ``vega_msgs`` message it will publish, with stamps
as integer milliseconds (:mod:`vega_sil.sim_timing` converts to ROS stamps):

* :class:`InsNode` — samples the truth every frame (100 Hz) with
  :class:`vega_plant.ins.InsSensor` (seeded noise); the measurement is stamped sample +
  sensor latency (12 ms). → :class:`InsOut` (``InsMeasurement``)
* :class:`ControllerNode` — every measurement whose sample time is a multiple of the
  controller period (20 ms) goes through :class:`vega_gnc.controller_runtime.ControllerRuntime`
  exactly as flown, at its arrival; the command is stamped arrival + computing latency (12 ms).
  → :class:`CommandOut` (``TvcCommand``)
* :class:`ActuatorNode` — applies each command at its stamp + actuator latency (15 ms), holds
  it until the next one, and integrates :class:`vega_plant.actuator.TvcActuator` (limits
  included) at the physics rate one frame at a time. → :class:`ActuatorOut` (``ActuatorState``)
"""

from __future__ import annotations

import bisect
from typing import NamedTuple

from vega_gnc.controller_runtime import ControllerRuntime, Measurement, RuntimeLimits
from vega_gnc.controller_table import ControllerTable
from vega_plant.actuator import ActuatorParams, TvcActuator
from vega_plant.ins import InsParams, InsSensor
from vega_plant.parameters import ModelParameters

from .sim_plant import TruthOut
from .sim_timing import LoopTiming

__all__ = ["InsOut", "CommandOut", "ActuatorOut", "InsNode", "ControllerNode", "ActuatorNode"]


class InsOut(NamedTuple):
    """One INS measurement: the fields of ``vega_msgs/InsMeasurement`` (SI units).

    ``stamp_ms`` is the header stamp (availability = sample + sensor latency), ``sample_ms``
    the truth time it represents.
    """

    stamp_ms: int
    sample_ms: int
    seq: int
    pitch_rad: float
    pitch_rate_radps: float
    drift_m: float
    drift_rate_mps: float
    velocity_mps: float
    valid: bool


class CommandOut(NamedTuple):
    """One nozzle command: the fields of ``vega_msgs/TvcCommand`` except the wall-clock
    ``compute_time_s``, which the node measures itself.

    ``stamp_ms`` = arrival of the measurement + computing latency; ``sample_ms`` = the
    measurement's sample time.
    """

    stamp_ms: int
    sample_ms: int
    seq: int
    deflection_cmd_rad: float
    scheduling_velocity_mps: float
    status: int


class ActuatorOut(NamedTuple):
    """The nozzle over one frame: the fields of ``vega_msgs/ActuatorState``.

    Samples at the ends of the frame's physics steps, oldest first; ``stamp_ms`` is the time
    of the last one. ``command_samples_rad`` (the command held over each step) is not carried
    by the message; a bag check rebuilds it from the ``TvcCommand`` stamps and the actuator
    latency.
    """

    stamp_ms: int
    seq: int
    deflection_samples_rad: tuple[float, ...]
    rate_samples_radps: tuple[float, ...]
    accel_samples_radps2: tuple[float, ...]
    command_samples_rad: tuple[float, ...]
    sample_period_s: float

    @property
    def deflection_rad(self) -> float:
        """Nozzle angle at the stamp [rad]."""
        return self.deflection_samples_rad[-1]

    @property
    def rate_radps(self) -> float:
        """Nozzle rate at the stamp [rad/s]."""
        return self.rate_samples_radps[-1]

    @property
    def accel_radps2(self) -> float:
        """Nozzle acceleration at the stamp [rad/s²]."""
        return self.accel_samples_radps2[-1]


def _check_ms(value_s: float, expected_ms: int, what: str) -> None:
    if abs(value_s * 1000.0 - expected_ms) > 1e-6:
        raise ValueError(f"{what} {value_s!r} s does not match the loop timing "
                         f"({expected_ms} ms)")


class InsNode:
    """INS sensor node: one measurement per frame.

    Parameters
    ----------
    params
        INS parameters (noise levels; rate and latency must match ``timing``).
    timing
        Loop timing (frame = INS period, sensor latency).
    seed
        Noise seed (:class:`vega_plant.ins.InsSensor`).
    noise
        False: exact kinematics.
    """

    def __init__(self, params: InsParams, timing: LoopTiming, seed: int, noise: bool = True):
        _check_ms(1.0 / params.rate_hz, timing.frame_ms, "INS period")
        _check_ms(params.latency_s, timing.sensor_latency_ms, "INS latency")
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
        s = self._sensor.measure(truth.state, model_params, truth.velocity_mps)
        out = InsOut(truth.stamp_ms + self._latency_ms, truth.stamp_ms, self._seq,
                     s.theta_rad, s.theta_dot_radps, s.z_m, s.z_dot_mps, s.velocity_mps, True)
        self._seq += 1
        return out


class ControllerNode:
    """Flight-controller node: the table-driven runtime at the controller rate.

    Parameters
    ----------
    table
        Validated controller table; its ``dt_s`` must be the controller period.
    timing
        Loop timing (controller period, computing latency).
    limits
        Runtime safety parameters.
    rate_mps2
        ρ̇ slice of a rate-dependent table (None: the runtime's default, the upper slice).

    Notes
    -----
    The runtime receives ``Measurement(stamp_s = sample time, …)`` and is stepped at
    ``now_s`` = the measurement's arrival (its stamp), so its staleness check sees the sensor
    latency (12 ms ≤ ``max_age_s``).
    """

    def __init__(self, table: ControllerTable, timing: LoopTiming,
                 limits: RuntimeLimits = RuntimeLimits(), rate_mps2: float | None = None):
        _check_ms(table.dt_s, timing.controller_period_ms, "controller table dt_s")
        self.runtime = ControllerRuntime(table, limits, rate_mps2)
        self._period_ms = timing.controller_period_ms
        self._latency_ms = timing.computing_latency_ms
        self._seq = 0

    def step(self, meas: InsOut) -> CommandOut | None:
        """Process one measurement; None if its sample time is not on the controller period."""
        if meas.sample_ms % self._period_ms:
            return None
        cmd = self.runtime.step(
            Measurement(meas.sample_ms / 1000.0, meas.pitch_rad, meas.pitch_rate_radps,
                        meas.drift_m, meas.drift_rate_mps, meas.velocity_mps, meas.valid),
            now_s=meas.stamp_ms / 1000.0)
        out = CommandOut(meas.stamp_ms + self._latency_ms, meas.sample_ms, self._seq,
                         cmd.deflection_cmd_rad, cmd.scheduling_velocity_mps, cmd.status)
        self._seq += 1
        return out


class ActuatorNode:
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
        _check_ms(params.dt_s, timing.physics_dt_ms, "actuator step")
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

    def receive(self, cmd: CommandOut) -> None:
        """Queue a command; it applies from ``cmd.stamp_ms`` + actuator latency."""
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
        pending, act, dt = self._pending, self._act, self._dt_ms
        step = act.step
        command = self._command
        samples = []
        for k in range(self._steps):
            while pending and pending[0][0] <= t_ms + k * dt:
                command = pending.pop(0)[2]
            # (β, β̇, β̈) and the finite command in force (a NaN/inf command holds the last)
            samples.append(step(command) + (act.command_rad,))
        self._command = command
        beta, rate, accel, held = zip(*samples)
        self._t_ms = t_ms + self._steps * dt
        out = ActuatorOut(self._t_ms, self._seq, beta, rate, accel, held, dt / 1000.0)
        self._seq += 1
        return out
