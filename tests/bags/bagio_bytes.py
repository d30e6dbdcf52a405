"""Bytes of run-bag messages and MCAP files for the bagio tests, derived by hand.

CDR (XCDR1, little endian): every primitive aligned to its size counted from the payload's
start, after the 4-byte encapsulation header; a string or sequence is a uint32 length, a
string's bytes include its NUL. :data:`INS_OFFSETS` are the offsets of an InsMeasurement's
fields worked out so from the .msg file; :func:`_raw` gives a sample message
(tests/msg_samples.py) serialised by rclpy, as a recorder receives it; :func:`_small_bag`
writes a short bag of them with :class:`vega_bags.bagio.RunBagWriter`.
"""

from rclpy.serialization import serialize_message

import msg_samples
from vega_bags import bagio
from vega_bus import topics

META = {k: "x" for k in bagio.REQUIRED_METADATA}
"""Run metadata with every required key (value "x")."""

MAGIC = b"\x89MCAP0\r\n"
"""The MCAP file's opening and closing magic bytes."""

# InsMeasurement (payload offsets, +4 for the encapsulation header):
#   header.stamp        sec @0, nanosec @4                        -> 4
#   header.frame_id     length @8, 9 chars + NUL ("vega_body")    -> 12, ends at 22
#   sample_stamp        aligned to 4: 24                          -> 28, ends at 32
#   seq (uint32)        32                                        -> 36
#   pitch_rad ...       float64, aligned to 8: 40, 48, 56, 64, 72 -> 44, 52, 60, 68, 76
#   valid (bool)        80                                        -> 84
INS_OFFSETS = {"stamp_ns": 4, "header.frame_id": 12, "sample_stamp_ns": 28, "seq": 36,
               "pitch_rad": 44, "pitch_rate_radps": 52, "drift_m": 60, "drift_rate_mps": 68,
               "velocity_mps": 76, "valid": 84}


def _raw(name, **fields):
    """The sample message ``name`` with some fields (dotted paths) replaced, serialised by
    rclpy."""
    message = msg_samples.to_ros(name)
    for key, value in fields.items():
        obj = message
        *parents, last = key.split(".")
        for p in parents:
            obj = getattr(obj, p)
        setattr(obj, last, value)
    return serialize_message(message)


def _small_bag(path, seconds=3):
    """A bag with /vega/ins messages over ``seconds`` of log time (several chunk flushes); its
    MCAP file."""
    raw = _raw("InsMeasurement")
    with bagio.RunBagWriter(path, META) as bag:
        for k in range(4 * seconds + 1):
            bag.write(topics.INS.name, k * 250_000_000, raw)
    (mcap,) = path.glob("*.mcap")
    return mcap
