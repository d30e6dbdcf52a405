"""The run-bag writer (:class:`vega_bags.bagio.RunBagWriter`): what it puts on disk and when.

metadata.yaml as ROS 2 Jazzy's recorder writes it (the offered QoS of every topic: RELIABLE,
VOLATILE, KEEP_LAST of depth vega_bus.topics.DATA_QUEUE_DEPTH, rclpy's infinite deadline,
lifespan and lease = 2^63 − 1 ns); the run-metadata JSON beside the MCAP file on disk as soon
as the bag is open (crash safety), its text exactly; metadata keys and values (strings or
numbers) checked before anything is created; open/write/close misuse refused; chunks on disk
every second of log time (FLUSH_PERIOD_NS = 1 s), read back from the file by hand while the
bag is still being written (MCAP records: opcode u8, length u64, body; chunk 0x06, message
0x05 inside).
"""

import struct

import pytest

from bagio_bytes import MAGIC, META, _raw
from vega_bags import bagio
from vega_bus import topics

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
