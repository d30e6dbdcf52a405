"""Timing of the closed loop: rates and latencies as integer milliseconds, and stamps.

Part of the node-graph contract: in the lockstep every node knows its producers' schedules
from these numbers, and converts stamps with these functions. Plain Python (no ROS, no
vehicle model): the flight side (vega_gnc) and the truth side (vega_plant) both import it.

Every time in the simulation is an integer number of milliseconds (flight time since the
ignition command), so that sampling, decimation and latencies are exact and two runs cannot
drift apart by rounding; seconds appear only at the interfaces (``ms / 1000``).

The loop (thesis §2.12.4 for the three latencies; rates from vehicle.yaml):

* physics (plant, wind, actuator) at 1 kHz, exchanged in frames of one INS period (10 ms);
* INS samples the truth at t = 10·k ms, the measurement is stamped sample + 12 ms;
* controller (50 Hz) processes the measurements whose sample time is a multiple of 20 ms, at
  their arrival, and stamps its command arrival + 12 ms;
* actuator applies a command at its stamp + 15 ms and holds it until the next one.

Sensor-to-nozzle latency 12 + 12 + 15 = 39 ms, plus the decimation phase (0…19 ms between
an event and the next sample the controller uses).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from vega_core.errors import BadInput

__all__ = ["NS_PER_MS", "NS_PER_S", "LoopTiming", "seconds_to_ms", "check_ms", "ms_to_stamp",
           "stamp_to_ms"]

# The time units of the graph, defined once (every package converts with these).
NS_PER_MS = 1_000_000
"""Nanoseconds per millisecond (ROS stamps and bag log times are in ns, the loop in ms)."""
NS_PER_S = 1_000_000_000
"""Nanoseconds per second (``builtin_interfaces/Time``: sec, nanosec)."""


def seconds_to_ms(value_s: float, what: str) -> int:
    """``value_s`` as a whole number of milliseconds.

    Raises
    ------
    BadInput
        If ``value_s`` is not finite or not a whole number of milliseconds (within 1e-6 ms).
    """
    ms = float(value_s) * 1000.0
    if ms != ms or ms in (float("inf"), float("-inf")):
        raise BadInput(f"{what} must be finite, got {value_s!r}")
    whole = round(ms)
    if abs(ms - whole) > 1e-6:
        raise BadInput(f"{what} = {value_s!r} s is not a whole number of milliseconds")
    return int(whole)


def check_ms(value_s: float, expected_ms: int, what: str) -> None:
    """Check that ``value_s`` seconds is ``expected_ms`` milliseconds (within 1e-6 ms).

    Raises
    ------
    BadInput
        One line naming ``what`` and both values.
    """
    if abs(value_s * 1000.0 - expected_ms) > 1e-6:
        raise BadInput(f"{what} {value_s!r} s does not match the loop timing "
                       f"({expected_ms} ms)")


def ms_to_stamp(t_ms: int) -> tuple[int, int]:
    """(sec, nanosec) of a ROS ``builtin_interfaces/Time`` for ``t_ms`` ≥ 0 (exact)."""
    sec, rest = divmod(int(t_ms), 1000)
    return sec, rest * NS_PER_MS


def stamp_to_ms(sec: int, nanosec: int) -> int:
    """Whole milliseconds of a (sec, nanosec) stamp (the inverse of :func:`ms_to_stamp`).

    Raises
    ------
    ValueError
        If the stamp is not on a whole millisecond.
    """
    ms, rest = divmod(int(nanosec), NS_PER_MS)
    if rest:
        raise ValueError(f"stamp {sec}.{int(nanosec):09d} s is not on a whole millisecond")
    return int(sec) * 1000 + ms


@dataclass(frozen=True)
class LoopTiming:
    """Rates and latencies of the loop [ms].

    Attributes
    ----------
    physics_dt_ms
        Physics step of the plant, wind and actuator (1 ms: 1 kHz).
    frame_ms
        Exchange frame = INS period (10 ms); the plant integrates one frame at a time.
    controller_period_ms
        Controller period (20 ms: 50 Hz), a multiple of the INS period.
    sensor_latency_ms, computing_latency_ms, actuator_latency_ms
        INS sample → measurement stamp; measurement arrival → command stamp; command stamp →
        application at the nozzle (thesis §2.12.4: 12, 12, 15 ms).
    """

    physics_dt_ms: int = 1
    frame_ms: int = 10
    controller_period_ms: int = 20
    sensor_latency_ms: int = 12
    computing_latency_ms: int = 12
    actuator_latency_ms: int = 15

    def __post_init__(self):
        for name in ("physics_dt_ms", "frame_ms", "controller_period_ms"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value > 0):
                raise BadInput(f"LoopTiming.{name} must be a positive integer, got {value!r}")
        for name in ("sensor_latency_ms", "computing_latency_ms", "actuator_latency_ms"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 0):
                raise BadInput(f"LoopTiming.{name} must be an integer >= 0, got {value!r}")
        if self.frame_ms % self.physics_dt_ms:
            raise BadInput("LoopTiming.frame_ms must be a multiple of physics_dt_ms")
        if self.controller_period_ms % self.frame_ms:
            raise BadInput("LoopTiming.controller_period_ms must be a multiple of frame_ms")

    @classmethod
    def from_vehicle(cls, data: Mapping[str, float], actuator_delay_deviation_s: float = 0.0
                     ) -> "LoopTiming":
        """Timing from vehicle.yaml (``actuator.physics_rate_hz``, ``ins.rate_hz``,
        ``controller.rate_hz``, ``delays.*``).

        Parameters
        ----------
        data
            Vehicle data (:class:`vega_model.vehicle_data.VehicleData`, or any mapping of
            those dotted keys to numbers).
        actuator_delay_deviation_s
            Added to the actuator latency: the ``delay_s`` deviation of the uncertainty set
            (±10 ms on the total, thesis §2.12.4), applied to the actuator delay
            (docs/ENVIRONMENT_MODELS.md §2).
        """
        return cls(
            physics_dt_ms=seconds_to_ms(1.0 / data["actuator.physics_rate_hz"], "physics step"),
            frame_ms=seconds_to_ms(1.0 / data["ins.rate_hz"], "INS period"),
            controller_period_ms=seconds_to_ms(1.0 / data["controller.rate_hz"],
                                               "controller period"),
            sensor_latency_ms=seconds_to_ms(data["delays.sensor_s"], "sensor delay"),
            computing_latency_ms=seconds_to_ms(data["delays.computing_s"], "computing delay"),
            actuator_latency_ms=seconds_to_ms(
                data["delays.actuator_s"] + actuator_delay_deviation_s, "actuator delay"),
        )

    @property
    def steps_per_frame(self) -> int:
        """Physics steps per frame."""
        return self.frame_ms // self.physics_dt_ms

    @property
    def total_latency_ms(self) -> int:
        """Sensor-to-nozzle latency without the decimation phase (thesis: 39 ms)."""
        return self.sensor_latency_ms + self.computing_latency_ms + self.actuator_latency_ms
