"""Topic names, message types and QoS of the VEGA TVC node graph (one source of truth).

Every node, the recorder, the bag checker and the replay tool use these names; a node may
still be remapped with ``--ros-args -r OLD:=NEW``. Message types are given as rosidl names
(``pkg/msg/Type``) so that this module imports without rclpy; :func:`message_class` loads
the generated Python class when a node needs it.

Data topics are RELIABLE, VOLATILE, KEEP_LAST with a deep queue: the lockstep keeps at most a
few frames in flight, so the depth only has to cover a slow subscriber, and nothing is ever
dropped silently (a sequence gap fails the run). ``/clock`` is published RELIABLE so that both
BEST_EFFORT (rclpy's default /clock subscription) and RELIABLE readers match, with the data
topics' depth so that the recorder's RELIABLE reader loses no tick when it lags (a writer's
KEEP_LAST history overwrites unacknowledged samples).

Every field of a data topic is a function of the flight (scenario, seed, controller table):
two runs of one scenario and seed give the same bytes on each. What the host measures (the
controller's wall-clock step time) goes to :data:`DIAGNOSTICS` (``/vega/diagnostics``,
``vega_msgs/StepDiagnostics``, data QoS), which is recorded beside the data topics (``vega
check`` reads the compute-time budget from it) and is the one recorded topic whose bytes differ
between runs. :data:`RECORD_ORDER` is the order of equal-time messages in a bag file.

Control topics carry the start and the pace of a run, not data (they are not recorded):
``/vega/recorded`` (std_msgs/UInt32, data QoS: the recorder's progress, the plant's
back-pressure; :mod:`vega_bus.schedule`), and
``/vega/ready`` (std_msgs/String: a participant's node name, once all its publishers have
matched their subscribers; :mod:`vega_bus.barrier`) and ``/vega/run`` (std_msgs/String: the
run description as JSON, published by the plant; :class:`vega_bus.schedule.RunInfo`), both
RELIABLE, TRANSIENT_LOCAL (late joiners get them), KEEP_LAST :data:`CONTROL_QUEUE_DEPTH`.
"""

from __future__ import annotations

import importlib
from typing import NamedTuple

__all__ = ["Topic", "TRUTH", "INS", "TVC_CMD", "ACTUATOR", "CLOCK", "DATA_TOPICS",
           "ALL_TOPICS", "DIAGNOSTICS", "RECORD_ORDER", "READY", "RUN", "RECORDED",
           "DATA_QUEUE_DEPTH", "CONTROL_QUEUE_DEPTH", "message_class"]

DATA_QUEUE_DEPTH = 1000  # messages; ≥ 10 s of the fastest topic (100 Hz) in flight
CONTROL_QUEUE_DEPTH = 10  # messages per writer of /vega/ready and /vega/run (each sends one)


class Topic(NamedTuple):
    """A topic of the graph: name, rosidl type name, publisher node, nominal rate [Hz]."""

    name: str
    type_name: str
    publisher: str
    rate_hz: float


# Nominal rates at the default timing (vehicle.yaml: 10 ms exchange frame, INS 100 Hz,
# controller 50 Hz); the actual rates follow the scenario's timing.
TRUTH = Topic("/vega/truth", "vega_msgs/msg/VehicleState", "plant", 100.0)
INS = Topic("/vega/ins", "vega_msgs/msg/InsMeasurement", "ins_sensor", 100.0)
TVC_CMD = Topic("/vega/tvc_cmd", "vega_msgs/msg/TvcCommand", "tvc_controller", 50.0)
ACTUATOR = Topic("/vega/actuator", "vega_msgs/msg/ActuatorState", "tvc_actuator", 100.0)
CLOCK = Topic("/clock", "rosgraph_msgs/msg/Clock", "plant", 10.0)   # vega_bus.schedule

# Wall-clock step diagnostics of the controller: one per command, stamp and seq of the command.
DIAGNOSTICS = Topic("/vega/diagnostics", "vega_msgs/msg/StepDiagnostics", "tvc_controller", 50.0)

DATA_TOPICS = (TRUTH, INS, TVC_CMD, ACTUATOR)
ALL_TOPICS = DATA_TOPICS + (CLOCK, DIAGNOSTICS)
"""Every recorded topic (a run bag holds these)."""
RECORD_ORDER = {t.name: i for i, t in enumerate(ALL_TOPICS)}
"""Topic name → rank: a bag holds its messages sorted by (log time, rank, seq), so that equal-time
messages of different topics sit in one order whatever order they arrived in."""

# Control topics (not recorded): publisher "*" = every participant.
READY = Topic("/vega/ready", "std_msgs/msg/String", "*", 0.0)
RUN = Topic("/vega/run", "std_msgs/msg/String", "plant", 0.0)
# Recorder progress (number of truth messages written), data QoS; the plant never runs more
# than vega_bus.schedule.RECORDER_WINDOW_FRAMES ahead of it (vega_bus.schedule).
RECORDED = Topic("/vega/recorded", "std_msgs/msg/UInt32", "recorder", 2.0)


def message_class(type_name: str):
    """The rosidl-generated Python class of ``pkg/msg/Type`` (imports the package)."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)
