"""The wire adapter (vega_bus.wire): records ↔ messages by field name.

Each record of vega_bus.records against the rosidl-generated class of its message
(``get_fields_and_field_types()``): the same fields by name, compatible types, the unit the
name promises in the .msg comment; record → message → record round trips (also through CDR);
the TvcCommand status constants taken from the message only.
"""

import math
import re

import pytest
from ament_index_python.packages import get_package_share_directory
from rclpy.serialization import deserialize_message, serialize_message

from vega_bus import topics, wire
from vega_bus.records import ActuatorOut, CommandOut, InsOut, TruthOut
from vega_bus.timing import NS_PER_MS

RECORDS = (TruthOut, InsOut, CommandOut, ActuatorOut)

# Message type (rosidl name in get_fields_and_field_types) → record annotations it accepts.
_TYPES = {"uint32": {"int"}, "uint8": {"int"}, "double": {"float"}, "boolean": {"bool"},
          "builtin_interfaces/Time": {"int"}, "double[2]": {"tuple[float, float]"},
          "sequence<double>": {"tuple[float, ...]"}}

# Unit suffix of a field name → unit in the .msg comment (longest suffix first).
_UNITS = (("_pa_rad", "Pa*rad"), ("_radps2", "rad/s^2"), ("_radps", "rad/s"), ("_rad", "rad"),
          ("_mps", "m/s"), ("_pa", "Pa"), ("_m", "m"), ("_s", "s"))


def _message_class(record):
    return topics.message_class(wire.WIRE[record].topic.type_name)


def _message_fields(cls) -> dict[str, str]:
    """Field (dotted, nested messages other than Time expanded) → rosidl type."""
    out = {}
    for name, kind in cls.get_fields_and_field_types().items():
        if kind == "std_msgs/Header":
            from std_msgs.msg import Header

            out.update({f"{name}.{k}": v for k, v in Header.get_fields_and_field_types().items()})
        else:
            out[name] = kind
    return out


def _units(cls) -> dict[str, str]:
    """Field → unit, from the ``[unit]`` comments of the installed .msg file."""
    path = f"{get_package_share_directory('vega_msgs')}/msg/{cls.__name__}.msg"
    units = {}
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            found = re.match(r"\s*[\w/\[\]<>=]+\s+(\w+)\s*#.*\[([^\]]+)\]\s*$", line)
            if found:
                units[found.group(1)] = found.group(2)
    return units


def _sample(record, k: int = 1):
    """A record with distinct, non-trivial values (stamps on the ms grid)."""
    values = []
    for name in record._fields:
        hint = wire.annotation(record, name)
        if name.endswith("_ms"):
            values.append(12_345 + 7 * k + len(values))
        elif name == "seq":
            values.append(4_000_000_000 + k)
        elif name == "status":
            values.append(max(wire.STATUS_NAMES))
        elif hint == "bool":
            values.append(k % 2 == 1)
        elif hint == "tuple[float, float]":
            values.append((0.1 * k, -math.pi / k))
        elif hint.startswith("tuple"):
            values.append(tuple(1e-3 * i * k - 0.5 for i in range(10)))
        else:
            values.append(math.sqrt(2.0) * (len(values) + k) / 3.0)
    return record._make(values)


def _carried(rec):
    """The record as it comes back from a message (fields not on the wire: ())."""
    return rec._replace(**{name: () for name in wire.WIRE[type(rec)].unsent})


# ----------------------------------------------------------------------------- fields
@pytest.mark.parametrize("record", RECORDS, ids=lambda r: r.__name__)
def test_record_fields_are_the_message_fields(record):
    """Every field the message carries is a record field of the same name (stamps: *_ms),
    except header.frame_id and the listed measured/derived fields; nothing else."""
    w = wire.WIRE[record]
    msg_fields = _message_fields(_message_class(record))
    mapped = wire.message_fields(record)
    expected = set(msg_fields) - {"header.frame_id", *w.measured, *w.derived}
    assert set(mapped.values()) == expected
    assert set(record._fields) - set(mapped) == set(w.unsent)
    for name in w.derived:      # written from the record's properties of the same name
        assert isinstance(getattr(record, name), property) and name in msg_fields


@pytest.mark.parametrize("record", RECORDS, ids=lambda r: r.__name__)
def test_record_types_and_units_match_the_message(record):
    cls = _message_class(record)
    msg_fields = _message_fields(cls)
    units = _units(cls)
    for name, path in wire.message_fields(record).items():
        hint = wire.annotation(record, name)
        kind = msg_fields[path]
        assert hint in _TYPES[kind], f"{record.__name__}.{name}: {hint} vs {path}: {kind}"
        suffix = next((u for s, u in _UNITS if name.endswith(s)), None)
        if suffix is not None and not name.endswith("_ms"):
            assert units.get(name) == suffix, f"{cls.__name__}.{name}: unit {units.get(name)}"


# ----------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("record", RECORDS, ids=lambda r: r.__name__)
def test_record_message_record_round_trip(record):
    cls = _message_class(record)
    for k in (1, 2, 3):
        rec = _sample(record, k)
        msg = wire.to_msg(rec, cls())
        assert wire.from_msg(record, msg) == _carried(rec)
        # and through the wire format, as a subscriber receives it
        again = deserialize_message(serialize_message(msg), cls)
        assert wire.from_msg(record, again) == _carried(rec)
        for name in wire.WIRE[record].derived:
            assert getattr(again, name) == getattr(rec, name)


def test_to_msg_fills_stamps_and_leaves_the_publishers_own_fields():
    from vega_msgs.msg import TvcCommand

    msg = TvcCommand()
    msg.header.frame_id = "base_link"
    rec = CommandOut(10_012, 10_000, 7, -0.01, 800.0, 2)
    wire.to_msg(rec, msg)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (10, 12 * NS_PER_MS)
    assert (msg.sample_stamp.sec, msg.sample_stamp.nanosec) == (10, 0)
    assert msg.header.frame_id == "base_link"


def test_no_wall_clock_field_on_a_data_topic():
    """Every field of a data message comes from the flight (the record or the publisher's
    constant frame_id); the controller's step time is on /vega/diagnostics."""
    from vega_msgs.msg import StepDiagnostics, TvcCommand

    assert "compute_time_s" not in TvcCommand.get_fields_and_field_types()
    assert all(not w.measured for w in wire.WIRE.values())
    assert topics.DIAGNOSTICS not in topics.DATA_TOPICS
    assert topics.DIAGNOSTICS in topics.ALL_TOPICS          # recorded
    assert topics.message_class(topics.DIAGNOSTICS.type_name) is StepDiagnostics
    assert list(StepDiagnostics.get_fields_and_field_types()) == ["header", "seq",
                                                                   "compute_time_s"]


def test_a_stamp_off_the_millisecond_grid():
    """Strict reading raises (the truth-side nodes: run failure); the controller's reading
    (bytes, as its node takes them) rounds down and marks the measurement invalid (its input
    validation), for either stamp."""
    from rclpy.serialization import serialize_message
    from vega_gnc.controller_node import sample_decoder
    from vega_msgs.msg import InsMeasurement

    to_sample = sample_decoder()
    msg = wire.to_msg(_sample(InsOut)._replace(valid=True), InsMeasurement())
    assert to_sample(serialize_message(msg)) == wire.from_msg(InsOut, msg)
    msg.sample_stamp.nanosec += 1
    with pytest.raises(ValueError, match="not on a whole millisecond"):
        wire.from_msg(InsOut, msg)
    got = to_sample(serialize_message(msg))
    assert got.valid is False and got.sample_ms == _sample(InsOut).sample_ms
    msg.sample_stamp.nanosec -= 1
    assert to_sample(serialize_message(msg)).valid is True      # the flag does not stick
    msg.header.stamp.nanosec += 999_999
    got = to_sample(serialize_message(msg))
    assert got.valid is False and got.stamp_ms == _sample(InsOut).stamp_ms


# ----------------------------------------------------------------------------- status
def test_status_constants_come_from_the_message():
    from vega_gnc import controller_runtime as runtime
    from vega_msgs.msg import TvcCommand

    names = [n for n in dir(TvcCommand) if n.startswith("STATUS_")]
    assert len(names) == 5
    for name in names:
        assert getattr(runtime, name) == getattr(TvcCommand, name), name
    assert wire.STATUS_NAMES == {getattr(TvcCommand, n): n[len("STATUS_"):] for n in names}
    assert list(wire.STATUS_NAMES) == sorted(wire.STATUS_NAMES)


def test_no_status_value_is_declared_outside_the_message():
    """No module assigns a literal to a STATUS_* name (they are all taken from TvcCommand)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    pattern = re.compile(r"^\s*STATUS_[A-Z_]+\s*=\s*\d", re.MULTILINE)
    offenders = [str(p.relative_to(root))
                 for base in ("ros2_ws/src", "offline", "cli", "bench")
                 for p in (root / base).rglob("*.py")
                 if "/build/" not in str(p) and "/install/" not in str(p)
                 and pattern.search(p.read_text(encoding="utf-8"))]
    assert offenders == []
