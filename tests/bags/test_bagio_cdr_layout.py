"""CDR layout of the run-bag messages and the fast column reader (vega_bags.bagio).

:func:`vega_bags.bagio.cdr_offsets` and the numpy column reader ``_fast_columns`` against
offsets derived by hand from the .msg files and the CDR rules (XCDR1, little endian: every
primitive aligned to its size counted from the payload's start, after the 4-byte
encapsulation header; a string or sequence is a uint32 length, a string's bytes include its
NUL), the values unpacked at those offsets with :mod:`struct`: strings of other lengths shift
what follows, empty sequences are not padded, fixed arrays and sequences of float64; layouts
that have no fixed form (arrays of strings or of messages) are refused. Offsets in bytes from
the start of the serialised message (InsMeasurement's: tests/bags/bagio_bytes.py).
"""

import struct

import numpy as np
import pytest
from rclpy.serialization import serialize_message

import msg_samples
from bagio_bytes import INS_OFFSETS, _raw
from vega_bags import bagio
from vega_bus import topics

# ActuatorState, frame_id "nozzle" (6 chars + NUL), three sequences of 10 float64:
#   stamp @0 -> 4; frame_id length @8 -> 12, ends at 19; seq aligned to 4: 20 -> 24;
#   deflection/rate/accel float64 @24, 32, 40 -> 28, 36, 44;
#   deflection_samples_rad length @48 -> 52, data aligned to 8: 56..136;
#   rate_samples_radps length @136 -> 140, data 144..224;
#   accel_samples_radps2 length @224 -> 228, data 232..312; sample_period_s @312 -> 316.
ACTUATOR_OFFSETS = {"stamp_ns": 4, "header.frame_id": 12, "seq": 24, "deflection_rad": 28,
                    "rate_radps": 36, "accel_radps2": 44, "deflection_samples_rad": 52,
                    "rate_samples_radps": 140, "accel_samples_radps2": 228,
                    "sample_period_s": 316}


def test_ins_offsets_are_the_hand_derived_layout():
    data = _raw("InsMeasurement")
    assert bagio.cdr_offsets(topics.INS.type_name, data) == INS_OFFSETS
    sample = msg_samples.SAMPLES["InsMeasurement"]
    assert struct.unpack_from("<iI", data, 4) == (1_700_000_123, 987_654_321)
    assert struct.unpack_from("<I", data, 12) == (len("vega_body") + 1,)
    assert struct.unpack_from("<iI", data, 28) == (1_700_000_123, 975_654_321)
    assert struct.unpack_from("<I", data, 36) == (sample["seq"],)
    for key in ("pitch_rad", "pitch_rate_radps", "drift_m", "drift_rate_mps", "velocity_mps"):
        assert struct.unpack_from("<d", data, INS_OFFSETS[key]) == (sample[key],), key
    assert data[84] == 1 and len(data) == 85


def test_a_longer_frame_id_shifts_what_follows():
    """frame_id of 12 chars + NUL ends at payload 8 + 4 + 13 = 25: sample_stamp re-aligns to
    28 and seq to 36 (data 32, 40); seq ends at 40, already aligned for the float64s, which so
    keep their places."""
    data = _raw("InsMeasurement", **{"header.frame_id": "b" * 12})
    got = bagio.cdr_offsets(topics.INS.type_name, data)
    assert got == {**INS_OFFSETS, "sample_stamp_ns": 32, "seq": 40}
    sample = msg_samples.SAMPLES["InsMeasurement"]
    assert struct.unpack_from("<I", data, 40) == (sample["seq"],)
    assert struct.unpack_from("<d", data, 44) == (sample["pitch_rad"],)


def test_actuator_offsets_with_sequences():
    data = _raw("ActuatorState")
    got = bagio.cdr_offsets(topics.ACTUATOR.type_name, data)
    assert got == ACTUATOR_OFFSETS
    sample = msg_samples.SAMPLES["ActuatorState"]
    for key, start in (("deflection_samples_rad", 60), ("rate_samples_radps", 148),
                       ("accel_samples_radps2", 236)):
        (n,) = struct.unpack_from("<I", data, got[key])
        assert n == len(sample[key]) == 10
        assert list(struct.unpack_from("<10d", data, start)) == sample[key], key
    assert struct.unpack_from("<d", data, 316) == (sample["sample_period_s"],)
    assert len(data) == 324


def test_empty_sequences_are_not_padded():
    """A sequence of length 0 is its uint32 length alone: nothing follows it to align."""
    data = _raw("ActuatorState", deflection_samples_rad=[], rate_samples_radps=[],
                accel_samples_radps2=[], **{"header.frame_id": "n"})
    # frame_id "n": length @8, 2 bytes, ends at 14; seq @16 -> 20; float64s @24, 32, 40;
    # three lengths @48, 52, 56 -> 52, 56, 60; sample_period_s aligned to 8: 64 -> 68
    got = bagio.cdr_offsets(topics.ACTUATOR.type_name, data)
    assert got == {"stamp_ns": 4, "header.frame_id": 12, "seq": 20, "deflection_rad": 28,
                   "rate_radps": 36, "accel_radps2": 44, "deflection_samples_rad": 52,
                   "rate_samples_radps": 56, "accel_samples_radps2": 60,
                   "sample_period_s": 68}
    assert struct.unpack_from("<d", data, 68) == \
        (msg_samples.SAMPLES["ActuatorState"]["sample_period_s"],)


def test_vehicle_state_fixed_arrays_and_tvc_command():
    data = _raw("VehicleState")
    got = bagio.cdr_offsets(topics.TRUTH.type_name, data)
    # frame_id "vega_body" ends at 22; seq @24 -> 28; 11 float64 @32..112 -> 36..116;
    # bending_q float64[2] @120 -> 124, bending_qdot @136 -> 140
    sample = msg_samples.SAMPLES["VehicleState"]
    assert got["seq"] == 28 and got["pitch_rad"] == 36 and got["wind_mps"] == 116
    assert got["bending_q"] == 124 and got["bending_qdot"] == 140
    assert list(struct.unpack_from("<2d", data, 124)) == sample["bending_q"]
    assert list(struct.unpack_from("<2d", data, 140)) == sample["bending_qdot"]
    assert len(data) == 156
    # TvcCommand: frame_id "tvc" (4 bytes) ends at 16; sample_stamp @16 -> 20; seq @24 -> 28;
    # float64 @32, 40 -> 36, 44; status (uint8) @48 -> 52
    data = _raw("TvcCommand")
    got = bagio.cdr_offsets(topics.TVC_CMD.type_name, data)
    assert got == {"stamp_ns": 4, "header.frame_id": 12, "sample_stamp_ns": 20, "seq": 28,
                   "deflection_cmd_rad": 36, "scheduling_velocity_mps": 44, "status": 52}
    assert data[52] == 4


def test_clock_offset_is_its_stamp():
    from rosgraph_msgs.msg import Clock

    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = 3, 5
    data = serialize_message(clock)
    assert bagio.cdr_offsets(topics.CLOCK.type_name, data) == {"stamp_ns": 4}
    assert struct.unpack_from("<iI", data, 4) == (3, 5)


def test_a_sequence_after_an_empty_one_is_aligned_from_its_length(tmp_path):
    """deflection_samples_rad empty: the rate samples' length ends at payload 56, a multiple
    of 8, so their float64s start right there (not 8 bytes on)."""
    rates = [0.25, -0.5, 0.75]
    data = _raw("ActuatorState", deflection_samples_rad=[], rate_samples_radps=rates,
                accel_samples_radps2=[])
    # frame_id "nozzle": seq -> 24; float64s -> 28, 36, 44; lengths @48, 52 (-> 52, 56);
    # rate data payload 56..80 (data 60); accel length @80 -> 84; sample_period_s @88 -> 92
    assert bagio.cdr_offsets(topics.ACTUATOR.type_name, data) == {
        **ACTUATOR_OFFSETS, "rate_samples_radps": 56, "accel_samples_radps2": 84,
        "sample_period_s": 92}
    assert list(struct.unpack_from("<3d", data, 60)) == rates
    assert struct.unpack_from("<d", data, 92) == (0.001,)
    assert len(data) >= 100         # the message ends at 100; rclpy's buffer may run on
    cols, counts = bagio._fast_columns(bagio.vega_typestore(), topics.ACTUATOR.type_name,
                                       [data, data])
    assert cols["rate_samples_radps"].tolist() == rates * 2
    assert counts["deflection_samples_rad"].tolist() == [0, 0]
    assert cols["sample_period_s"].tolist() == [0.001, 0.001]


def test_layouts_it_cannot_compute_are_refused():
    """Arrays of strings or of messages have no fixed layout: cdr_offsets (and so the fast
    column reader, which then falls back to the deserialiser) refuses them with _NotFlat."""
    store = bagio.vega_typestore()
    joint = store.types["sensor_msgs/msg/JointState"]
    header = store.types["std_msgs/msg/Header"]
    time = store.types["builtin_interfaces/msg/Time"]
    msg = joint(header=header(stamp=time(sec=1, nanosec=2), frame_id="j"), name=["a", "b"],
                position=np.zeros(2), velocity=np.zeros(0), effort=np.zeros(0))
    data = bytes(store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    with pytest.raises(bagio._NotFlat, match="name"):
        bagio.cdr_offsets("sensor_msgs/msg/JointState", data)
    array = store.types["diagnostic_msgs/msg/DiagnosticArray"](
        header=header(stamp=time(sec=1, nanosec=2), frame_id=""), status=[])
    data = bytes(store.serialize_cdr(array, "diagnostic_msgs/msg/DiagnosticArray"))
    with pytest.raises(bagio._NotFlat, match="status"):
        bagio.cdr_offsets("diagnostic_msgs/msg/DiagnosticArray", data)


def test_the_fast_reader_itself_reads_the_samples():
    """_fast_columns on its own (read_run_bag falls back to the deserialiser whenever it
    gives up, which hides a fast reader that gives up on good input): three messages of each
    type with seq 0, 1, 2 and the sample's other values, read to the documented columns."""
    store = bagio.vega_typestore()
    for name in msg_samples.TYPE_NAMES:
        sample = msg_samples.SAMPLES[name]
        raw = [_raw(name, seq=k) for k in range(3)]
        cols, counts = bagio._fast_columns(store, f"vega_msgs/msg/{name}", raw)
        stamp = sample["header"]["stamp"]
        assert cols.pop("stamp_ns").tolist() == [stamp["sec"] * 10**9 + stamp["nanosec"]] * 3
        for field, value in sample.items():
            if field == "header":
                continue
            if field == "sample_stamp":
                got = cols.pop("sample_stamp_ns")
                assert got.dtype == np.int64
                assert got.tolist() == [value["sec"] * 10**9 + value["nanosec"]] * 3
                continue
            got = cols.pop(field)
            if field == "seq":
                assert got.dtype == np.int64 and got.tolist() == [0, 1, 2]
            elif isinstance(value, bool):
                assert got.dtype == bool and got.tolist() == [value] * 3
            elif isinstance(value, int):
                assert got.dtype == np.int64 and got.tolist() == [value] * 3, field
            elif isinstance(value, float):
                assert got.dtype == np.float64 and got.tolist() == [value] * 3, field
            elif field in counts:                       # sequence: flattened, with counts
                assert got.dtype == np.float64 and got.tolist() == value * 3, field
                assert counts.pop(field).tolist() == [len(value)] * 3
            else:                                       # fixed array: (N, k)
                assert got.dtype == np.float64 and got.tolist() == [value] * 3, field
        assert cols == {} and counts == {}, name
