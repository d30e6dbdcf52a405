"""Plain records of messages that cross the flight/truth boundary, stamps in integer ms.

The INS measurement is produced on the truth side (:class:`vega_sim.device_steps.InsStep`) and
consumed on the flight side (:class:`vega_gnc.controller_step.ControllerStep`); neither package
imports the other, so its record lives here, in the contract both share.
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["InsOut"]


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
