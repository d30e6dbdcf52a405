"""Plain records of the messages of the node graph, stamps in integer ms.

One record per data message, its fields those of the ``vega_msgs`` message by name and unit
(:mod:`vega_bus.wire` converts between the two by field name; tests/bus/test_wire.py checks the
names against the rosidl-generated classes):

* :class:`TruthOut` — ``VehicleState``, produced by :class:`vega_sim.plant_step.PlantStep`;
* :class:`InsOut` — ``InsMeasurement``, produced by :class:`vega_sim.device_steps.InsStep`
  on the truth side and consumed by :class:`vega_gnc.controller_step.ControllerStep` on the
  flight side;
* :class:`CommandOut` — ``TvcCommand``, produced by the controller step;
* :class:`ActuatorOut` — ``ActuatorState``, produced by
  :class:`vega_sim.device_steps.ActuatorStep`.

The truth side and the flight side never import each other, and the wire adapter sits below
both, so the records live here, in the contract they all share. Plain Python (no ROS).
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["TruthOut", "InsOut", "CommandOut", "ActuatorOut"]


class TruthOut(NamedTuple):
    """Truth at one frame time: the fields of ``vega_msgs/VehicleState`` (SI units).

    ``dynamic_pressure_pa``, ``mach``, ``velocity_mps`` and ``altitude_m`` are those of the
    reference trajectory at the stamp (the model parameters); ``aoa_rad`` is the kinematic
    angle of attack at the CP (:func:`vega_model.dynamics.angle_of_attack`) and
    ``q_alpha_pa_rad`` the plant's own Qα output; ``wind_mps`` the wind held over the
    physics step that starts at the stamp.
    """

    stamp_ms: int
    seq: int
    pitch_rad: float
    pitch_rate_radps: float
    drift_m: float
    drift_rate_mps: float
    aoa_rad: float
    q_alpha_pa_rad: float
    dynamic_pressure_pa: float
    mach: float
    velocity_mps: float
    altitude_m: float
    wind_mps: float
    bending_q: tuple[float, float]
    bending_qdot: tuple[float, float]

    @property
    def state(self) -> tuple[float, ...]:
        """The plant state in :data:`vega_model.dynamics.STATES` order."""
        return (self.pitch_rad, self.pitch_rate_radps, self.drift_m, self.drift_rate_mps,
                *self.bending_q, *self.bending_qdot)


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
    """One nozzle command: the fields of ``vega_msgs/TvcCommand`` (the controller node's
    wall-clock step time goes to ``/vega/diagnostics``, not here).

    ``stamp_ms`` = arrival of the measurement + computing latency; ``sample_ms`` = the
    measurement's sample time; ``status`` one of the message's ``STATUS_*`` constants.
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
    by the message (a record read from one holds ``()``); a bag check rebuilds it from the
    ``TvcCommand`` stamps and the actuator latency. The message's ``deflection_rad``,
    ``rate_radps`` and ``accel_radps2`` are the last samples (the properties below).
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
