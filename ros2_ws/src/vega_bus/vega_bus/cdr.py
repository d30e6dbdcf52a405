"""Records ↔ serialised messages (CDR bytes) without rclpy's message objects: the SIL nodes'
fast path on the lockstep topics.

Why: in the 5-process SIL flight most of a node's Python time per message went into rclpy
turning CDR into a message object (and back) and into :mod:`vega_bus.wire` moving the fields
between that object and a record — ≈ 15–18 µs per message each way, measured
(docs/SIL_SPEED.md), for ≈ 8 messages a node sends or takes per 10 ms frame. A subscription
created with ``raw=True`` hands over the serialised bytes, and ``Publisher.publish(bytes)``
sends serialised bytes; :func:`encoder` and :func:`decoder` pack and unpack them with one
precompiled :class:`struct.Struct` per message layout (≈ 2 µs).

The layout is not written here: it is derived from the rosidl-generated message class
(``get_fields_and_field_types``, in declaration order; nested types resolved by their
package), with the field rule of :mod:`vega_bus.wire` (record ``x_ms`` ↔ message ``x_stamp``
/ ``header.stamp``; derived and unsent fields as :data:`vega_bus.wire.WIRE` lists them), so the
``.msg`` files stay the one source of truth. Encoding: plain CDR, little-endian, as ROS 2
serialises for Fast DDS — the 4-byte encapsulation header ``00 01 00 00``; every primitive
aligned to its size counted from the byte after that header; a string as its uint32 length
(with the terminating NUL), its bytes and the NUL; a sequence as its uint32 length and its
elements; a fixed array as its elements. Padding bytes are zero (rclpy's own serialiser leaves
whatever was in memory there; no reader looks at them). tests/bus/test_cdr.py holds the
bytes equal to ``rclpy.serialization.serialize_message`` outside the padding and the decoded
records equal to :func:`vega_bus.wire.from_msg`, for every record type, over generated values.

Plain Python: imports the message classes for their field lists, never rclpy.
"""

from __future__ import annotations

import importlib
import struct
from typing import Callable

from vega_bus import wire
from vega_bus.timing import ms_to_stamp, stamp_to_ms

__all__ = ["ENCAPSULATION", "encoder", "decoder", "layout"]

ENCAPSULATION = b"\x00\x01\x00\x00"
"""CDR, little-endian, no options: the first four bytes of every serialised message."""

# IDL primitive → (struct code, size [bytes] = alignment)
_PRIMITIVES = {
    "boolean": ("?", 1), "octet": ("B", 1), "uint8": ("B", 1), "int8": ("b", 1),
    "char": ("B", 1), "uint16": ("H", 2), "int16": ("h", 2), "uint32": ("I", 4),
    "int32": ("i", 4), "uint64": ("Q", 8), "int64": ("q", 8), "float": ("f", 4),
    "double": ("d", 8),
}
_PRIM, _STRING, _ARRAY, _SEQUENCE = range(4)


def _message_class(type_name: str):
    """``pkg/Type`` or ``pkg/msg/Type`` → the rosidl-generated class."""
    parts = type_name.split("/")
    package, name = parts[0], parts[-1]
    return getattr(importlib.import_module(f"{package}.msg"), name)


def layout(msg_class) -> tuple[tuple, ...]:
    """The leaves of a message type in serialisation order: ``(path, kind, code, size, n)``,
    ``path`` the dotted field path, ``kind`` one of primitive / string / fixed array (``n``
    elements) / sequence."""
    leaves = []
    for name, type_text in msg_class.get_fields_and_field_types().items():
        if type_text in _PRIMITIVES:
            code, size = _PRIMITIVES[type_text]
            leaves.append((name, _PRIM, code, size, 1))
        elif type_text == "string":
            leaves.append((name, _STRING, "", 4, 0))
        elif type_text.startswith("sequence<") and type_text[9:-1] in _PRIMITIVES:
            code, size = _PRIMITIVES[type_text[9:-1]]
            leaves.append((name, _SEQUENCE, code, size, 0))
        elif type_text.endswith("]") and type_text.split("[")[0] in _PRIMITIVES:
            base, count = type_text[:-1].split("[")
            code, size = _PRIMITIVES[base]
            leaves.append((name, _ARRAY, code, size, int(count)))
        elif "/" in type_text and "<" not in type_text and "[" not in type_text:
            leaves.extend((f"{name}.{path}", *rest)
                          for path, *rest in layout(_message_class(type_text)))
        else:
            raise TypeError(f"{msg_class.__name__}.{name}: type {type_text!r} is not "
                            f"supported by vega_bus.cdr")
    return tuple(leaves)


class _Compiled:
    """One concrete layout (string and sequence lengths fixed): its Struct and, per leaf, the
    slice of the unpacked values that holds it (a length field is a value of its own)."""

    def __init__(self, leaves, lengths: tuple[int, ...]):
        fmt, offset, slots, it = ["<4x"], 0, [], iter(lengths)
        index = 0
        for _path, kind, code, size, n in leaves:
            if kind in (_STRING, _SEQUENCE):
                pad = -offset % 4
                fmt.append("x" * pad + "I")
                offset += pad + 4
                index += 1
                count = next(it)
                if kind == _STRING:
                    fmt.append(f"{count}s")
                    offset += count
                    slots.append((index, index + 1))
                    index += 1
                    continue
                n = count
            pad = -offset % size if n else 0
            fmt.append("x" * pad + f"{n}{code}")
            offset += pad + n * size
            slots.append((index, index + n))
            index += n
        self.struct = struct.Struct("".join(fmt))
        self.slots = tuple(slots)
        self.lengths = lengths


def _lengths(leaves, data) -> tuple[int, ...]:
    """The string and sequence lengths of serialised ``data`` (walked leaf by leaf)."""
    offset, lengths = 4, []
    for _path, kind, _code, size, n in leaves:
        if kind in (_STRING, _SEQUENCE):
            offset += -(offset - 4) % 4
            if offset + 4 > len(data):
                raise ValueError(f"{len(data)} bytes: too short for the message's layout")
            (count,) = struct.unpack_from("<I", data, offset)
            offset += 4
            lengths.append(count)
            if kind == _STRING:
                offset += count
                continue
            n = count
        if n:
            offset += -(offset - 4) % size + n * size
    if offset > len(data):
        raise ValueError(f"{len(data)} bytes: too short for the message's layout")
    return tuple(lengths)


def _record_plan(record_type, leaves):
    """Per message leaf, where its value comes from in the record:
    ``("sec" | "nanosec", record field)`` for a stamp, ``("frame_id", None)``,
    ``("value", name)`` otherwise (a record field or a derived property)."""
    to_field = {path: name for name, path in wire.message_fields(record_type).items()}
    to_field.update({name: name for name in wire.WIRE[record_type].derived})
    plan = []
    for path, *_ in leaves:
        head, _, last = path.rpartition(".")
        if last in ("sec", "nanosec") and head in to_field:
            plan.append((last, to_field[head]))
        elif path == "header.frame_id":
            plan.append(("frame_id", None))
        elif path in to_field:
            plan.append(("value", to_field[path]))
        else:
            raise TypeError(f"{record_type.__name__}: message field {path!r} has no source")
    return plan


def encoder(record_type, frame_id: str = "") -> Callable[[tuple], bytes]:
    """``record → CDR bytes`` of the record's topic message (:data:`vega_bus.wire.WIRE`),
    ``header.frame_id`` = ``frame_id``."""
    leaves = layout(_message_class(wire.WIRE[record_type].topic.type_name))
    plan = _record_plan(record_type, leaves)
    text = frame_id.encode() + b"\x00"
    cache: dict[tuple, struct.Struct] = {}
    stamp_fields = sorted({name for what, name in plan if what in ("sec", "nanosec")})

    def encode(record) -> bytes:
        stamps = {name: ms_to_stamp(getattr(record, name)) for name in stamp_fields}
        values, lengths = [], []
        for (what, name), (_path, kind, *_rest) in zip(plan, leaves):
            if what == "sec":
                values.append(stamps[name][0])
            elif what == "nanosec":
                values.append(stamps[name][1])
            elif what == "frame_id":
                lengths.append(len(text))
                values += (len(text), text)
            elif kind == _SEQUENCE:
                items = getattr(record, name)
                lengths.append(len(items))
                values.append(len(items))
                values += items
            elif kind == _ARRAY:
                values += getattr(record, name)
            else:
                values.append(getattr(record, name))
        key = tuple(lengths)
        packer = cache.get(key)
        if packer is None:
            packer = cache[key] = _Compiled(leaves, key).struct
        return ENCAPSULATION + packer.pack(*values)[4:]

    return encode


def decoder(record_type, stamp_ms: Callable[[int, int], int] = stamp_to_ms
            ) -> Callable[[bytes], tuple]:
    """``CDR bytes → record`` (the inverse of :func:`encoder`; like
    :func:`vega_bus.wire.from_msg` on the deserialised message).

    ``stamp_ms``: (sec, nanosec) → whole milliseconds for every stamp (default
    :func:`vega_bus.timing.stamp_to_ms`, which raises ``ValueError`` off the ms grid).
    Raises ``ValueError`` for bytes that are not a CDR little-endian message of the layout.
    Up to 3 bytes after the last field are accepted: Fast DDS delivers a payload padded to
    a multiple of 4 bytes (measured: an 85-byte ``InsMeasurement`` arrives as 88 bytes, the
    same whether it was published as a message object or as bytes).
    """
    leaves = layout(_message_class(wire.WIRE[record_type].topic.type_name))
    plan = _record_plan(record_type, leaves)
    wire_type = wire.WIRE[record_type]
    by_size: dict[tuple[int, int], _Compiled] = {}
    by_lengths: dict[tuple, _Compiled] = {}
    length_slots = [i for i, (_p, kind, *_r) in enumerate(leaves) if kind in (_STRING, _SEQUENCE)]

    def build(compiled: _Compiled):
        """Record field → how to read it from the unpacked values."""
        where = {}
        for (what, name), (start, stop), (_p, kind, *_r) in zip(plan, compiled.slots, leaves):
            if what in ("sec", "nanosec"):
                where.setdefault(name, [None, None])[0 if what == "sec" else 1] = start
            elif what == "value" and name not in wire_type.derived:
                where[name] = (kind, start, stop)
        steps = []
        for name in record_type._fields:
            if name in wire_type.unsent:
                steps.append((3, 0, 0))
            elif isinstance(where[name], list):
                steps.append((0, *where[name]))
            else:
                kind, start, stop = where[name]
                steps.append((2, start, stop) if kind in (_ARRAY, _SEQUENCE) else (1, start, 0))
        return tuple(steps)

    def decode(data) -> tuple:
        data = bytes(data)
        if data[:2] != ENCAPSULATION[:2]:
            raise ValueError(f"not a little-endian CDR message (header {data[:4].hex()})")
        key = (len(data), data[12] if len(data) > 12 else -1)
        entry = by_size.get(key)
        if entry is not None:
            compiled, steps = entry
            values = compiled.struct.unpack_from(data)
            if any(values[compiled.slots[i][0] - 1] != n
                   for i, n in zip(length_slots, compiled.lengths)):
                entry = None
        if entry is None:
            lengths = _lengths(leaves, data)
            entry = by_lengths.get(lengths)
            if entry is None:
                compiled = _Compiled(leaves, lengths)
                entry = by_lengths[lengths] = (compiled, build(compiled))
            compiled, steps = entry
            if not 0 <= len(data) - compiled.struct.size < 4:
                raise ValueError(f"{len(data)} bytes: the layout needs {compiled.struct.size} "
                                 f"(+ up to 3 bytes of padding)")
            by_size[key] = entry
            values = compiled.struct.unpack_from(data)
        out = []
        for what, a, b in steps:
            if what == 1:
                out.append(values[a])
            elif what == 0:
                out.append(stamp_ms(values[a], values[b]))
            elif what == 2:
                out.append(values[a:b])
            else:
                out.append(())
        return record_type._make(out)

    return decode
