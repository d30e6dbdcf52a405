"""vega_bus.cdr: records ↔ CDR bytes without message objects, checked against two independent
implementations: rosbags' CDR serialiser (writes zero padding: the same bytes exactly) and
rclpy's (``serialize_message`` / ``deserialize_message``; its padding bytes are whatever was
in memory, so the comparison with it goes through rclpy's own decoding)."""

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message

from vega_bags.bagio import vega_typestore
from vega_bus import cdr, topics, wire
from vega_bus.records import ActuatorOut, CommandOut, InsOut, TruthOut
from vega_bus.timing import NS_PER_MS

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
ms = st.integers(min_value=0, max_value=2**31 * 1000 - 1)   # int32 seconds
u32 = st.integers(min_value=0, max_value=2**32 - 1)


def _records():
    truth = st.builds(TruthOut, ms, u32, *([floats] * 11), st.tuples(floats, floats),
                      st.tuples(floats, floats))
    ins = st.builds(InsOut, ms, ms, u32, *([floats] * 5), st.booleans())
    cmd = st.builds(CommandOut, ms, ms, u32, floats, floats,
                    st.integers(min_value=0, max_value=255))
    samples = st.integers(min_value=1, max_value=12).flatmap(
        lambda n: st.tuples(*([st.lists(floats, min_size=n, max_size=n).map(tuple)] * 3)))
    act = st.builds(lambda s, seq, lists, dt: ActuatorOut(s, seq, *lists, (), dt),
                    ms, u32, samples, floats)
    return st.one_of(truth, ins, cmd, act)


def _message(record, frame_id):
    msg = topics.message_class(wire.WIRE[type(record)].topic.type_name)()
    wire.to_msg(record, msg)
    msg.header.frame_id = frame_id
    return msg


def _same(a, b):
    """Records equal field by field, NaN equal to NaN."""
    assert type(a) is type(b)
    for x, y in zip(a, b):
        if isinstance(x, tuple):
            assert len(x) == len(y) and all(u == v or (math.isnan(u) and math.isnan(v))
                                            for u, v in zip(x, y))
        else:
            assert x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(record=_records(), frame_id=st.sampled_from(["", "b", "base_link", "tvc_controller"]))
def test_bytes_are_the_serialisers_bytes(record, frame_id):
    """Encoded bytes = rosbags' serialisation of the same message (zero padding: byte for
    byte); rclpy reads them back as the message the record fills; decoding rclpy's own
    serialisation gives the record back (what wire.from_msg reads from the message)."""
    msg = _message(record, frame_id)
    type_name = wire.WIRE[type(record)].topic.type_name
    store = vega_typestore()
    data = cdr.encoder(type(record), frame_id)(record)
    reference = bytes(store.serialize_cdr(
        store.deserialize_cdr(bytes(serialize_message(msg)), type_name), type_name))
    assert data == reference
    back = deserialize_message(data, type(msg))
    _same(wire.from_msg(type(record), back), wire.from_msg(type(record), msg))
    _same(cdr.decoder(type(record))(serialize_message(msg)), wire.from_msg(type(record), msg))


def test_layout_follows_the_message_definition():
    """The leaves come from the generated class: Header first (stamp sec/nanosec, frame_id),
    VehicleState's fixed arrays, ActuatorState's sequences, InsMeasurement's bool last."""
    from vega_msgs.msg import ActuatorState, InsMeasurement, VehicleState

    truth = cdr.layout(VehicleState)
    assert [leaf[0] for leaf in truth[:4]] == ["header.stamp.sec", "header.stamp.nanosec",
                                              "header.frame_id", "seq"]
    assert truth[-1][0] == "bending_qdot" and truth[-1][4] == 2
    act = {leaf[0]: leaf for leaf in cdr.layout(ActuatorState)}
    assert act["deflection_samples_rad"][4] == 0 and act["deflection_samples_rad"][2] == "d"
    assert cdr.layout(InsMeasurement)[-1][:3] == ("valid", 0, "?")


def test_hand_computed_bytes_of_a_command():
    """TvcCommand, frame_id "ab": every offset by hand (CDR alignment counted after the
    4-byte encapsulation header)."""
    record = CommandOut(stamp_ms=1_234_567, sample_ms=1_234_555, seq=9,
                        deflection_cmd_rad=-0.25, scheduling_velocity_mps=400.5, status=4)
    data = cdr.encoder(CommandOut, "ab")(record)
    expected = (b"\x00\x01\x00\x00"
                + struct.pack("<iI", 1234, 567 * NS_PER_MS)      # header.stamp      0..8
                + struct.pack("<I", 3) + b"ab\x00" + b"\x00"     # frame_id + pad    8..16
                + struct.pack("<iI", 1234, 555 * NS_PER_MS)      # sample_stamp     16..24
                + struct.pack("<I", 9) + b"\x00" * 4             # seq + pad        24..32
                + struct.pack("<dd", -0.25, 400.5)               # two doubles      32..48
                + b"\x04")                                       # status           48
    assert data == expected
    assert cdr.decoder(CommandOut)(expected) == record


def test_decoder_rejects_what_is_not_the_layout():
    """A stamp off the millisecond grid raises like wire.from_msg (the caller turns it into
    its one line); bytes of another length or big-endian CDR are refused."""
    good = cdr.encoder(InsOut, "x")(InsOut(10, 0, 1, 0.0, 0.0, 0.0, 0.0, 100.0, True))
    decode = cdr.decoder(InsOut)
    assert decode(good).stamp_ms == 10
    off_grid = good[:8] + struct.pack("<I", 10 * NS_PER_MS + 1) + good[12:]
    with pytest.raises(ValueError, match="millisecond"):
        decode(off_grid)
    floor = cdr.decoder(InsOut, lambda sec, nanosec: sec * 1000 + nanosec // NS_PER_MS)
    assert floor(off_grid).stamp_ms == 10
    assert decode(good + b"\x00\x00\x00") == decode(good)   # DDS pads to 4 bytes
    with pytest.raises(ValueError):
        decode(good + b"\x00" * 4)
    with pytest.raises(ValueError):
        decode(good[:-1])
    with pytest.raises(ValueError):
        decode(good + b"\x00" * 8)
    for cut in (0, 4, 10, 13, 40):       # truncated anywhere, before or after a length
        with pytest.raises(ValueError):
            decode(good[:cut] if cut >= 2 else b"")
    with pytest.raises(ValueError, match="little-endian"):
        decode(b"\x00\x00" + good[2:])


def test_sequence_lengths_change_between_messages():
    """Two ActuatorState layouts of the same total size (10+10+10 and 9+11+10 samples): the
    decoder does not reuse the first layout for the second."""
    encode, decode = cdr.encoder(ActuatorOut, "a"), cdr.decoder(ActuatorOut)
    a = ActuatorOut(10, 1, tuple(map(float, range(10))), tuple(map(float, range(10))),
                    tuple(map(float, range(10))), (), 0.001)
    b = ActuatorOut(20, 2, tuple(map(float, range(9))), tuple(map(float, range(11))),
                    tuple(map(float, range(10))), (), 0.001)
    da, db = encode(a), encode(b)
    assert len(da) == len(db)
    assert decode(da) == a and decode(db) == b and decode(da) == a
