"""Records ↔ messages by field name: the one adapter between :mod:`vega_bus.records` and
the ``vega_msgs`` messages.

The bags of the in-process run (:mod:`vega_bags.simbag`) fill a message from a record with
:func:`to_msg`; :func:`from_msg` reads one back (the reference tests/bus holds
:mod:`vega_bus.cdr` against); the SIL nodes
(:mod:`vega_plant.nodes`, :mod:`vega_gnc.controller_node`) go straight between records and
serialised bytes with :mod:`vega_bus.cdr`, whose layout follows this module's field rule and
plan (tests/bus/test_cdr.py: the same bytes as a message filled by :func:`to_msg`).

Field rule (tests/bus/test_wire.py checks it against the rosidl-generated classes):

* ``stamp_ms`` ↔ ``header.stamp`` and ``<name>_ms`` ↔ ``<name>_stamp`` (``sample_ms`` ↔
  ``sample_stamp``): integer milliseconds ↔ ``builtin_interfaces/Time``
  (:func:`vega_bus.timing.ms_to_stamp`; read back with :func:`vega_bus.timing.stamp_to_ms`,
  which rejects a stamp off the millisecond grid, unless the caller passes its own
  conversion);
* every other record field ↔ the message field of the same name, in the same unit (the name
  carries it: ``_rad``, ``_radps``, ``_m``, ``_mps``, ``_pa``, ``_s``, …); arrays and
  sequences are tuples of floats in a record;
* not carried (:class:`WireType`): ``header.frame_id`` (each publisher sets it once);
  ``ActuatorState.deflection_rad``, ``rate_radps``, ``accel_radps2`` (the last samples:
  written from :class:`~vega_bus.records.ActuatorOut`'s properties, not read back);
  ``ActuatorOut.command_samples_rad`` (not on the wire: ``()`` in a record read from a
  message).

:data:`STATUS_NAMES` names the ``TvcCommand`` status values, from the message definition (the
only place they are declared; :mod:`vega_gnc.controller_runtime` takes its ``STATUS_*`` from
there too).

Plain Python: works on any object with the message's attributes; imports the message
classes (for the status constants), never rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from operator import attrgetter
from typing import Any, Callable

from vega_msgs.msg import TvcCommand

from vega_bus import topics
from vega_bus.records import ActuatorOut, CommandOut, InsOut, TruthOut
from vega_bus.timing import ms_to_stamp, stamp_to_ms

__all__ = ["WireType", "WIRE", "STATUS_NAMES", "stamp_field", "message_fields", "annotation",
           "to_msg", "from_msg"]


@dataclass(frozen=True)
class WireType:
    """How one record travels: its topic (hence message type) and the fields not carried.

    Attributes
    ----------
    record
        The record class (:mod:`vega_bus.records`).
    topic
        The topic of its messages (:mod:`vega_bus.topics`).
    derived
        Message fields written from record properties of the same name, not read back.
    measured
        Message fields the publisher sets itself (not in the record).
    unsent
        Record fields not carried by the message (``()`` in a record read from one).
    """

    record: type
    topic: topics.Topic
    derived: tuple[str, ...] = ()
    measured: tuple[str, ...] = ()
    unsent: tuple[str, ...] = ()


WIRE: dict[type, WireType] = {w.record: w for w in (
    WireType(TruthOut, topics.TRUTH),
    WireType(InsOut, topics.INS),
    WireType(CommandOut, topics.TVC_CMD),
    WireType(ActuatorOut, topics.ACTUATOR,
             derived=("deflection_rad", "rate_radps", "accel_radps2"),
             unsent=("command_samples_rad",)),
)}
"""Record class → :class:`WireType`, one per data topic."""

STATUS_NAMES: dict[int, str] = dict(sorted(
    (getattr(TvcCommand, name), name[len("STATUS_"):])
    for name in dir(TvcCommand) if name.startswith("STATUS_")))
"""``TvcCommand.status`` value → name without the ``STATUS_`` prefix (``OK``, ``HOLD_LAST``, …),
ordered by value; from the message definition."""


def stamp_field(record_field: str) -> str | None:
    """The message's ``builtin_interfaces/Time`` field (dotted path) of a ``*_ms`` record
    field (``stamp_ms`` → ``header.stamp``, ``sample_ms`` → ``sample_stamp``); None for any
    other field."""
    if record_field == "stamp_ms":
        return "header.stamp"
    if record_field.endswith("_ms"):
        return record_field[:-len("_ms")] + "_stamp"
    return None


def message_fields(record_type: type) -> dict[str, str]:
    """Record field → message field (dotted path) of every field the message carries."""
    wire = WIRE[record_type]
    return {name: stamp_field(name) or name for name in record_type._fields
            if name not in wire.unsent}


# One plan per record type, built once: (record field, kind, accessor).
_TIME, _VALUE, _ARRAY, _UNSENT = range(4)


def annotation(record_type: type, name: str) -> str:
    """The type annotation of a record field as written (``"float"``,
    ``"tuple[float, float]"``; NamedTuple keeps it as a forward reference)."""
    hint = record_type.__annotations__[name]
    return str(getattr(hint, "__forward_arg__", hint))


def _plan(record_type: type) -> tuple[tuple[str, int, Any], ...]:
    wire = WIRE[record_type]
    plan = []
    for name in record_type._fields:
        path = stamp_field(name)
        if name in wire.unsent:
            plan.append((name, _UNSENT, None))
        elif path is not None:
            plan.append((name, _TIME, attrgetter(path)))
        elif annotation(record_type, name).startswith("tuple"):
            plan.append((name, _ARRAY, None))
        else:
            plan.append((name, _VALUE, None))
    return tuple(plan)


_PLANS = {record_type: _plan(record_type) for record_type in WIRE}


def to_msg(record, msg):
    """Fill ``msg`` (a message of the record's topic) from ``record`` by field name; returns
    ``msg``. Leaves ``header.frame_id`` and the publisher's own fields
    (:attr:`WireType.measured`) as they are."""
    record_type = type(record)
    for name, kind, get in _PLANS[record_type]:
        if kind == _TIME:
            stamp = get(msg)
            stamp.sec, stamp.nanosec = ms_to_stamp(getattr(record, name))
        elif kind != _UNSENT:
            setattr(msg, name, getattr(record, name))
    for name in WIRE[record_type].derived:
        setattr(msg, name, getattr(record, name))
    return msg


def from_msg(record_type: type, msg,
             stamp_ms: Callable[[int, int], int] = stamp_to_ms):
    """The record of type ``record_type`` that ``msg`` carries, read by field name.

    Parameters
    ----------
    record_type
        A record class of :data:`WIRE`.
    msg
        A message of its topic's type (or anything with those attributes).
    stamp_ms
        (sec, nanosec) → whole milliseconds, for every stamp field (default
        :func:`vega_bus.timing.stamp_to_ms`).

    Raises
    ------
    ValueError
        From ``stamp_ms``: with the default, a stamp that is not on a whole millisecond.
    """
    values = []
    for name, kind, get in _PLANS[record_type]:
        if kind == _TIME:
            stamp = get(msg)
            values.append(stamp_ms(stamp.sec, stamp.nanosec))
        elif kind == _VALUE:
            values.append(getattr(msg, name))
        elif kind == _ARRAY:
            values.append(tuple(map(float, getattr(msg, name))))
        else:
            values.append(())
    return record_type._make(values)
