"""Run-bag writer, CDR layout and reader: tests written for the survivors of the full
`make mutation MODULE=bagio` run (docs/TESTING.md).

Independent references: CDR offsets derived by hand from the .msg files and the CDR rules
(XCDR1, little endian: every primitive aligned to its size counted from the payload's start,
after the 4-byte encapsulation header; a string or sequence is a uint32 length, a string's
bytes include its NUL), the values unpacked at those offsets with :mod:`struct`; the bag files
read back with plain rosbags and :mod:`zlib`, never through the code under test.
"""

import struct

import numpy as np
import pytest
from rclpy.serialization import serialize_message

import msg_samples
from vega_bags import bagio
from vega_bus import topics

META = {k: "x" for k in bagio.REQUIRED_METADATA}


# ----------------------------------------------------------------------------- CDR layout
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


def _raw(name, **fields):
    message = msg_samples.to_ros(name)
    for key, value in fields.items():
        obj = message
        *parents, last = key.split(".")
        for p in parents:
            obj = getattr(obj, p)
        setattr(obj, last, value)
    return serialize_message(message)


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


# ----------------------------------------------------------------------------- RunBag
def test_run_bag_has_only_its_topics(tmp_path):
    path = tmp_path / "bag"
    with bagio.RunBagWriter(path, META) as bag:
        bag.write(topics.INS.name, 1, _raw("InsMeasurement"))
    run = bagio.read_run_bag(path)
    assert run.has(topics.INS.name) is True
    assert run.has("/vega/nothing") is False
    with pytest.raises(bagio.BagError, match=r"no topic /vega/nothing"):
        run["/vega/nothing"]


# ----------------------------------------------------------------------------- MCAP CRCs
MAGIC = b"\x89MCAP0\r\n"


def _footer_fields(data):
    """(summary_start, summary_offset_start, summary_crc, footer offset) read by hand: the
    footer record (opcode 0x02, length 20) sits right before the closing magic."""
    at = len(data) - 8 - 29
    op, length, start, offset_start, crc = struct.unpack_from("<BQQQI", data, at)
    assert data[-8:] == MAGIC and op == 0x02 and length == 20
    return start, offset_start, crc, at


def _small_bag(path, seconds=3):
    """A bag with /vega/ins messages over ``seconds`` of log time (several chunk flushes)."""
    raw = _raw("InsMeasurement")
    with bagio.RunBagWriter(path, META) as bag:
        for k in range(4 * seconds + 1):
            bag.write(topics.INS.name, k * 250_000_000, raw)
    (mcap,) = path.glob("*.mcap")
    return mcap


def test_section_crcs_are_the_zlib_crcs_of_the_specified_bytes(tmp_path):
    """MCAP specification: DataEnd's CRC covers the file from its first byte to the DataEnd
    record; the footer's summary CRC covers the summary section through the footer's
    summary_offset_start field. Both written, both non-zero."""
    import zlib

    from mcap.reader import make_reader

    mcap = _small_bag(tmp_path / "bag")
    data = mcap.read_bytes()
    start, offset_start, summary_crc, footer_at = _footer_fields(data)
    assert 8 < start < offset_start < footer_at
    end_at = start - 13
    op, length, data_crc = struct.unpack_from("<BQI", data, end_at)
    assert (op, length) == (0x0F, 4)
    assert data_crc == zlib.crc32(data[:end_at]) != 0
    assert summary_crc == zlib.crc32(data[start:footer_at + 1 + 8 + 8 + 8]) != 0
    # the chunk records' own CRCs: of their uncompressed records
    pos, chunks = 8, 0
    while data[pos] != 0x0F:
        (size,) = struct.unpack_from("<Q", data, pos + 1)
        if data[pos] == 0x06:
            body = data[pos + 9:pos + 9 + size]
            (records_size,) = struct.unpack_from("<Q", body, 16)
            (crc,) = struct.unpack_from("<I", body, 24)
            (n,) = struct.unpack_from("<I", body, 28)
            records = body[32 + n + 8:]
            assert len(records) == records_size and crc == zlib.crc32(records) != 0
            chunks += 1
        pos += 9 + size
    assert chunks >= 4          # the schema chunk + one per second of log time
    # Foxglove's reader, validating every CRC, reads all 13 messages
    with open(mcap, "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) == 13


def test_a_flipped_byte_in_the_data_section_is_refused(tmp_path):
    import zlib

    mcap = _small_bag(tmp_path / "bag")
    data = bytearray(mcap.read_bytes())
    start, _, _, _ = _footer_fields(data)
    stored = struct.unpack_from("<I", data, start - 4)[0]
    at = bytes(data).rfind(_raw("InsMeasurement")) + INS_OFFSETS["pitch_rad"]
    data[at] ^= 0x01
    mcap.write_bytes(bytes(data))
    computed = zlib.crc32(bytes(data[:start - 13]))
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(tmp_path / "bag")
    assert str(info.value) == (f"bag {tmp_path / 'bag'}: corrupt data ({mcap.name}: data "
                               f"section CRC {stored:08x} stored, {computed:08x} computed)")
    with pytest.raises(bagio.BagError, match="data section CRC"):
        bagio.check_section_crcs(tmp_path / "bag")
    # a stray file without a footer, sorted first, is passed over: the bag's file is checked
    (tmp_path / "bag" / "0_stray.mcap").write_bytes(MAGIC + b"no footer here")
    with pytest.raises(bagio.BagError, match=f"{mcap.name}: data section CRC"):
        bagio.check_section_crcs(tmp_path / "bag")


def test_a_flipped_byte_in_the_summary_is_refused(tmp_path):
    import zlib

    mcap = _small_bag(tmp_path / "bag")
    data = bytearray(mcap.read_bytes())
    start, _, stored, footer_at = _footer_fields(data)
    data[start + 20] ^= 0x01
    mcap.write_bytes(bytes(data))
    computed = zlib.crc32(bytes(data[start:footer_at + 25]))
    with pytest.raises(bagio.BagError) as info:
        bagio.check_section_crcs(tmp_path / "bag")
    assert str(info.value) == (f"bag {tmp_path / 'bag'}: corrupt data ({mcap.name}: summary "
                               f"CRC {stored:08x} stored, {computed:08x} computed)")


def test_zero_crcs_are_not_checked(tmp_path):
    """0 means "not computed" (MCAP): a bag whose section CRCs are zeroed reads as before."""
    mcap = _small_bag(tmp_path / "bag")
    data = bytearray(mcap.read_bytes())
    start, _, _, footer_at = _footer_fields(data)
    data[start - 4:start] = bytes(4)
    data[footer_at + 25:footer_at + 29] = bytes(4)
    mcap.write_bytes(bytes(data))
    bagio.check_section_crcs(tmp_path / "bag")
    assert len(bagio.read_run_bag(tmp_path / "bag")[topics.INS.name]) == 13
    # a flipped payload byte under zeroed section CRCs: the chunk CRC still finds it
    at = bytes(data).rfind(_raw("InsMeasurement")) + INS_OFFSETS["pitch_rad"]
    data[at] ^= 0x01
    mcap.write_bytes(bytes(data))
    bagio.check_section_crcs(tmp_path / "bag")
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(tmp_path / "bag")
    assert str(info.value).startswith(f"bag {tmp_path / 'bag'}: corrupt data (")
    assert "crc" in str(info.value).lower() and "section" not in str(info.value)


def _synthetic(summary=b"", data_crc=0x11223344, summary_crc=0x55667788, op_end=0x0F,
               op_footer=0x02, len_end=4, len_footer=20):
    """magic, DataEnd, [summary], Footer, magic: a minimal MCAP file built by hand."""
    head = MAGIC + struct.pack("<BQI", op_end, len_end, data_crc)
    start = len(head) if summary else 0
    return head + summary + struct.pack("<BQQQI", op_footer, len_footer, start, 0,
                                        summary_crc) + MAGIC


def test_section_crcs_of_hand_built_files():
    import zlib

    # no summary (summary_start 0): DataEnd right before the footer
    data = _synthetic()
    assert bagio._section_crcs(data) == (8, 0x11223344, zlib.crc32(data[:8]), 21,
                                         0x55667788, zlib.crc32(data[21:46]))
    # a 16-byte summary between them
    data = _synthetic(summary=bytes(range(16)))
    assert bagio._section_crcs(data) == (8, 0x11223344, zlib.crc32(data[:8]), 37,
                                         0x55667788, zlib.crc32(data[21:62]))
    # not an MCAP file's end: each wrong field alone gives None
    for bad in (_synthetic(op_end=0x0E), _synthetic(op_footer=0x03), _synthetic(len_end=5),
                _synthetic(len_footer=21), _synthetic()[:-1] + b"\x00", b"",
                MAGIC + struct.pack("<BQQQI", 0x02, 20, 0, 0, 0) + MAGIC):
        assert bagio._section_crcs(bad) is None, bad
    # the smallest file whose footer follows the opening magic directly: no room for DataEnd
    assert bagio._section_crcs(MAGIC[:0] + _synthetic()[21:]) is None


def test_write_section_crcs_fills_both(tmp_path):
    import zlib

    path = tmp_path / "x.mcap"
    path.write_bytes(_synthetic(summary=b"summary!", data_crc=0, summary_crc=0))
    bagio.write_section_crcs(path)
    data = path.read_bytes()
    assert struct.unpack_from("<I", data, 17)[0] == zlib.crc32(data[:8])
    footer_at = len(data) - 37
    assert struct.unpack_from("<I", data, footer_at + 25)[0] == \
        zlib.crc32(data[21:footer_at + 25])
    assert len(data) == 8 + 13 + 8 + 29 + 8
    path.write_bytes(b"not an mcap file at all, long enough to hold a footer" * 2)
    with pytest.raises(bagio.BagError, match="no MCAP footer after closing"):
        bagio.write_section_crcs(path)


# ----------------------------------------------------------------------------- the writer
INFINITE = {"sec": 9_223_372_036, "nsec": 854_775_807}   # RMW_DURATION_INFINITE = 2^63 - 1 ns


def test_offered_qos_of_every_topic_is_jazzys_record_of_the_publishers_profile(tmp_path):
    """metadata.yaml as Jazzy's recorder writes it for a RELIABLE, VOLATILE, KEEP_LAST
    publisher of depth vega_bus.topics.DATA_QUEUE_DEPTH (vega_bus.qos), with rclpy's default
    infinite deadline, lifespan and lease."""
    import yaml

    assert INFINITE["sec"] * 1_000_000_000 + INFINITE["nsec"] == 2**63 - 1
    path = tmp_path / "bag"
    bagio.RunBagWriter(path, META).open().close()
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    want = {"avoid_ros_namespace_conventions": False, "deadline": INFINITE,
            "depth": topics.DATA_QUEUE_DEPTH, "durability": "volatile",
            "history": "keep_last", "lifespan": INFINITE, "liveliness": "automatic",
            "liveliness_lease_duration": INFINITE, "reliability": "reliable"}
    listed = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert list(listed) == [t.name for t in topics.ALL_TOPICS]
    for topic in topics.ALL_TOPICS:
        entry = listed[topic.name]
        assert entry["message_count"] == 0
        assert entry["topic_metadata"]["type"] == topic.type_name
        assert entry["topic_metadata"]["offered_qos_profiles"] == [want], topic.name
    assert info["ros_distro"] == "jazzy" and info["message_count"] == 0


def test_run_metadata_file_is_on_disk_once_open(tmp_path):
    """Crash safety: the JSON beside the MCAP file exists before anything is written; its text
    exactly (sorted keys, one-space indent, final newline)."""
    path = tmp_path / "bag"
    meta = {**META, bagio.META_SEED: 7, "vega.dt": 0.5}
    writer = bagio.RunBagWriter(path, meta)
    assert writer.metadata[bagio.META_SEED] == "7" and writer.metadata["vega.dt"] == "0.5"
    assert not writer.is_open and not path.exists()
    writer.open()
    try:
        assert writer.is_open
        assert bagio.run_metadata_path(path) == path / "vega_run_metadata.json"
        assert (path / "vega_run_metadata.json").read_text() == (
            '{\n'
            ' "custom_data": {\n'
            '  "vega.controller_table": "x",\n'
            '  "vega.controller_table_sha256": "x",\n'
            '  "vega.dt": "0.5",\n'
            '  "vega.git_revision": "x",\n'
            '  "vega.scenario": "x",\n'
            '  "vega.scenario_yaml": "x",\n'
            '  "vega.seed": "7"\n'
            ' },\n'
            ' "format": "vega_run_metadata",\n'
            ' "version": 1\n'
            '}\n')
    finally:
        writer.close()
    assert not writer.is_open
    writer.close()                                          # idempotent
    assert writer.counts == {t.name: 0 for t in topics.ALL_TOPICS}


def test_metadata_values_must_be_strings_or_numbers(tmp_path):
    for bad in ({**META, "x": True}, {**META, "x": None}, {**META, "x": b"raw"},
                {**META, 3: "x"}):
        with pytest.raises(ValueError, match="keys and values must be strings"):
            bagio.RunBagWriter(tmp_path / "a", bad)
    for key in bagio.REQUIRED_METADATA:
        with pytest.raises(ValueError, match=f"missing {key}$"):
            bagio.RunBagWriter(tmp_path / "a", {k: v for k, v in META.items() if k != key})
    ok = bagio.RunBagWriter(tmp_path / "a", {**META, "i": -4, "f": 1e-3})
    assert ok.metadata == {**META, "i": "-4", "f": "0.001"}
    assert not (tmp_path / "a").exists()                   # nothing created before open()


def test_open_twice_write_closed_and_an_impossible_path(tmp_path):
    writer = bagio.RunBagWriter(tmp_path / "b", META)
    with pytest.raises(ValueError, match="not open"):
        writer.write(topics.INS.name, 0, b"")
    writer.open()
    with pytest.raises(ValueError, match="already open"):
        writer.open()
    writer.close()
    with pytest.raises(ValueError, match="not open"):
        writer.write(topics.INS.name, 0, b"")
    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError):
        bagio.RunBagWriter(tmp_path / "file" / "bag", META).open()


def _on_disk(mcap):
    """Log times of the messages in the chunks already on disk of a bag still being written
    (MCAP records: opcode u8, length u64, body; chunk 0x06, message 0x05 inside)."""
    data = mcap.read_bytes()
    assert data[:8] == MAGIC
    pos, times = 8, []
    while pos + 9 <= len(data):
        op, (size,) = data[pos], struct.unpack_from("<Q", data, pos + 1)
        if pos + 9 + size > len(data):
            break
        if op == 0x06:
            body = data[pos + 9:pos + 9 + size]
            (n,) = struct.unpack_from("<I", body, 28)
            inner, at = body[32 + n + 8:], 0
            while at + 9 <= len(inner):
                iop, (isize,) = inner[at], struct.unpack_from("<Q", inner, at + 1)
                if iop == 0x05:
                    times.append(struct.unpack_from("<Q", inner, at + 9 + 6)[0])
                at += 9 + isize
        pos += 9 + size
    return times


def test_chunks_reach_the_disk_every_second_of_log_time(tmp_path):
    """FLUSH_PERIOD_NS = 1 s after the first message: a message at t >= that closes the chunk
    (itself included) and the next flush is due 1 s after it."""
    path = tmp_path / "bag"
    raw = _raw("InsMeasurement")
    writer = bagio.RunBagWriter(path, META).open()
    try:
        (mcap,) = path.glob("*.mcap")
        assert _on_disk(mcap) == []
        assert b"vega_msgs/msg/InsMeasurement" in mcap.read_bytes()   # schemas flushed
        t0 = 3_000_000_000
        for t in (t0, t0 + 500_000_000, t0 + 999_999_999):
            writer.write(topics.INS.name, t, raw)
        assert _on_disk(mcap) == []
        writer.write(topics.INS.name, t0 + 1_000_000_000, raw)
        assert _on_disk(mcap) == [t0, t0 + 500_000_000, t0 + 999_999_999, t0 + 1_000_000_000]
        writer.write(topics.INS.name, t0 + 1_999_999_999, raw)
        assert len(_on_disk(mcap)) == 4
        writer.write(topics.INS.name, t0 + 2_000_000_000, raw)
        assert _on_disk(mcap)[-2:] == [t0 + 1_999_999_999, t0 + 2_000_000_000]
        writer.write(topics.CLOCK.name, t0 + 2_500_000_000, b"\x00\x01\x00\x00" + bytes(8))
        assert writer.counts == {**{t.name: 0 for t in topics.ALL_TOPICS},
                                 topics.INS.name: 6, topics.CLOCK.name: 1}
    finally:
        writer.close()
    assert len(_on_disk(mcap)) == 7


# ----------------------------------------------------------------------------- the reader
def _plain_bag(path, entries, metadata=None):
    """A bag written by plain rosbags (no vega code): entries (topic, type, [(t, raw)])."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = bagio.vega_typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for key, value in (metadata or {}).items():
            writer.set_custom_data(key, value)
        conns = [(writer.add_connection(topic, msgtype, typestore=store), msgs)
                 for topic, msgtype, msgs in entries]
        for conn, msgs in conns:
            for t, raw in msgs:
                writer.write(conn, t, raw)
    return path


def _string_msg(text):
    store = bagio.vega_typestore()
    return bytes(store.serialize_cdr(store.types["std_msgs/msg/String"](data=text),
                                     "std_msgs/msg/String"))


def test_other_topics_are_listed_and_ignored(tmp_path):
    ins = _raw("InsMeasurement")
    path = _plain_bag(tmp_path / "bag", [
        ("/zeta", "std_msgs/msg/String", [(1, _string_msg("z"))]),
        (topics.INS.name, topics.INS.type_name, [(2, ins), (3, ins)]),
        ("/alpha", "std_msgs/msg/String", [(4, _string_msg("a"))]),
        (topics.CLOCK.name, topics.CLOCK.type_name, []),
    ], metadata={"vega.seed": "11"})
    bag = bagio.read_run_bag(path)
    assert bag.other_topics == ("/alpha", "/zeta")
    assert set(bag.topics) == {topics.INS.name, topics.CLOCK.name}
    assert bag.metadata == {"vega.seed": "11"} and bag.path == str(path)
    assert bag[topics.INS.name].log_time_ns.tolist() == [2, 3]
    assert bag[topics.INS.name].log_time_ns.dtype == np.int64
    clock = bag[topics.CLOCK.name]
    assert (clock.topic, clock.type_name) == (topics.CLOCK.name, topics.CLOCK.type_name)
    assert (bag[topics.INS.name].topic, bag[topics.INS.name].type_name) == \
        (topics.INS.name, topics.INS.type_name)
    assert clock.log_time_ns.dtype == np.int64 and clock.log_time_ns.shape == (0,)
    assert len(clock) == 0 and list(clock.columns) == ["stamp_ns"]
    assert clock["stamp_ns"].shape == (0,) and clock["stamp_ns"].dtype == np.int64
    assert [(t, n) for t, n, _ in bagio.iter_raw_messages(path)] == \
        [(topics.INS.name, 2), (topics.INS.name, 3)]
    assert list(bagio.iter_raw_messages(path, {"/alpha"})) == []
    assert list(bagio.iter_raw_messages(path, [topics.INS.name]))[1][2] == ins


def test_only_clock_is_a_foreign_bag(tmp_path):
    """/clock alone is no run bag: at least one data topic (vega_bus.topics.DATA_TOPICS)."""
    path = _plain_bag(tmp_path / "bag", [(topics.CLOCK.name, topics.CLOCK.type_name, []),
                                         (topics.DIAGNOSTICS.name,
                                          topics.DIAGNOSTICS.type_name, [])])
    with pytest.raises(bagio.BagError, match=r"foreign bag: none of the vega topics.*it "
                                             r"holds no topics$"):
        bagio.read_run_bag(path)
    with pytest.raises(bagio.BagError, match="foreign bag"):
        list(bagio.iter_raw_messages(path))
    assert bagio.read_run_bag(_plain_bag(tmp_path / "b2", [
        (topics.TRUTH.name, topics.TRUTH.type_name, [])])).topics.keys() == {topics.TRUTH.name}


def test_a_count_in_metadata_yaml_other_than_the_files_is_refused(tmp_path):
    import yaml

    path = _small_bag(tmp_path / "bag")
    path = path.parent
    meta = path / "metadata.yaml"
    tree = yaml.safe_load(meta.read_text())
    for entry in tree["rosbag2_bagfile_information"]["topics_with_message_count"]:
        if entry["topic_metadata"]["name"] == topics.INS.name:
            entry["message_count"] = 12
    meta.write_text(yaml.safe_dump(tree, sort_keys=False))
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(path)
    assert str(info.value) == (f"bag {path}: metadata.yaml lists 12 messages on "
                               f"{topics.INS.name}, the MCAP file holds 13")


def test_big_endian_messages_are_read_by_the_deserialiser(tmp_path):
    """The fast reader takes little-endian CDR only; big-endian messages (encapsulation
    0x0000) come back through rosbags' deserialiser with the same values."""
    store = bagio.vega_typestore()
    little = _raw("InsMeasurement")
    msg = store.deserialize_cdr(little, topics.INS.type_name)
    big = bytes(store.serialize_cdr(msg, topics.INS.type_name, little_endian=False))
    assert big[:2] == b"\x00\x00" and len(big) == len(little)
    sample = msg_samples.SAMPLES["InsMeasurement"]
    for first, second in ((big, big), (little, big)):
        path = _plain_bag(tmp_path / f"bag{len(list(tmp_path.iterdir()))}",
                          [(topics.INS.name, topics.INS.type_name, [(1, first), (2, second)])])
        cols = bagio.read_run_bag(path)[topics.INS.name]
        assert cols["pitch_rad"].tolist() == [sample["pitch_rad"]] * 2
        assert cols["seq"].tolist() == [sample["seq"]] * 2 and cols["seq"].dtype == np.int64
        assert cols["valid"].dtype == bool and cols["valid"].tolist() == [True, True]
        assert cols["stamp_ns"].tolist() == [1_700_000_123_987_654_321] * 2
    with pytest.raises(bagio._NotFlat):
        bagio._fast_columns(store, topics.INS.type_name, [big])
    with pytest.raises(bagio._NotFlat):
        bagio._fast_columns(store, topics.INS.type_name, [little, big])


def test_a_truncated_message_is_undecodable(tmp_path):
    ins = _raw("InsMeasurement")
    path = _plain_bag(tmp_path / "bag", [(topics.INS.name, topics.INS.type_name,
                                          [(1, ins[:60]), (2, ins[:60])])])
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(path)
    assert str(info.value).startswith(f"bag {path}: topic /vega/ins: undecodable "
                                      f"vega_msgs/msg/InsMeasurement message (")
    with pytest.raises(bagio._NotFlat):
        bagio._fast_columns(bagio.vega_typestore(), topics.INS.type_name, [ins[:84]])
    # one byte more than the layout (CDR padding at the end) still takes the fast path
    cols, _ = bagio._fast_columns(bagio.vega_typestore(), topics.INS.type_name,
                                  [ins + b"\x00"])
    assert cols["valid"].tolist() == [True]


def test_topics_without_messages_have_empty_columns_of_the_right_shapes(tmp_path):
    """What a check reads from a topic with no messages: every column, empty, with the
    message's shape (float64[2] -> (0, 2); sequences (0,) with (0,) counts)."""
    path = _plain_bag(tmp_path / "bag", [
        (topics.TRUTH.name, topics.TRUTH.type_name, []),
        (topics.ACTUATOR.name, topics.ACTUATOR.type_name, []),
        (topics.TVC_CMD.name, topics.TVC_CMD.type_name, [])])
    bag = bagio.read_run_bag(path)
    truth = bag[topics.TRUTH.name]
    assert truth["bending_q"].shape == (0, 2) and truth["bending_qdot"].shape == (0, 2)
    assert truth["stamp_ns"].dtype == np.int64 and truth["seq"].dtype == np.int64
    assert truth["mach"].dtype == np.float64 and truth["mach"].shape == (0,)
    act = bag[topics.ACTUATOR.name]
    for key in ("deflection_samples_rad", "rate_samples_radps", "accel_samples_radps2"):
        assert act[key].shape == (0,) and act[key].dtype == np.float64, key
        assert act.counts[key].shape == (0,) and act.counts[key].dtype == np.int64, key
    cmd = bag[topics.TVC_CMD.name]
    assert set(cmd.columns) == {"stamp_ns", "sample_stamp_ns", "seq", "deflection_cmd_rad",
                                "scheduling_velocity_mps", "status"}
    assert cmd["status"].dtype == np.int64 and cmd["sample_stamp_ns"].dtype == np.int64


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


def test_a_foreign_bag_names_what_it_holds_sorted(tmp_path):
    path = _plain_bag(tmp_path / "bag", [("/b", "std_msgs/msg/String", [(1, _string_msg("b"))]),
                                         ("/a", "std_msgs/msg/String", [(2, _string_msg("a"))])])
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(path)
    assert str(info.value) == (f"bag {path}: foreign bag: none of the vega topics (/vega/truth, "
                               f"/vega/ins, /vega/tvc_cmd, /vega/actuator); it holds /a, /b")
