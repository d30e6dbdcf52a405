"""A run bag as foreign tools see it: Foxglove's ``mcap`` reader with the
``mcap-ros2-support`` decoder, which decodes every message from the ``ros2msg`` schema text
stored in the file — none of our code, none of the installed message classes.

The bag is a short in-process run written by the run-bag writer the recorder uses
(``fixture_bags``). What a foreign reader must find in it:

* every message of every topic decodes, and the count per topic equals ``metadata.yaml`` and
  the MCAP summary statistics;
* the decoded field values equal the messages that were serialised (rclpy), rosbags' view and
  our own column reader;
* every channel carries ``topic_type_hash`` = the RIHS01 hash rosidl generated for its type,
  as Jazzy's rosbag2 writes and reads it;
* messages in log-time order in the file;
* chunk, data-section and summary CRCs present (non-zero) and right.

Each check is a function that raises ``AssertionError``; the negative tests feed it bags with
one defect each (schema fields swapped, a hash missing or wrong, a message dropped or moved,
CRCs left out, a flipped payload bit) and require it to fail — and an unaltered rewrite of the
bag to pass, so that the failures come from the defect.
"""

import json
import shutil
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer
from mcap_ros2.decoder import DecoderFactory

import msg_samples
from fixture_bags import short_run, write_bag
from vega_bags import bagio
from vega_bus import topics

SPAN_S = (20.0, 23.0)
"""Span of the run [s]: 3 s of the thesis scenario, every topic present (clock at 10 Hz)."""


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """(bag directory, [(topic, log time [ns], rclpy message)] serialised into it)."""
    run = short_run(tmp_path_factory.mktemp("run"), span_s=SPAN_S)
    messages = []  # filled by write_bag's mutate hook, which then leaves the list unchanged
    bag = write_bag(tmp_path_factory.mktemp("bag") / "bag", run, mutate=messages.extend)
    return bag, messages


@pytest.fixture(scope="module")
def bag(written):
    return written[0]


def _mcap(bag_dir) -> Path:
    (path,) = sorted(Path(bag_dir).glob("*.mcap"))
    return path


def _info(bag_dir) -> dict:
    return yaml.safe_load((Path(bag_dir) / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"]


def _plain(decoded):
    """Nested dict of a message decoded by mcap_ros2 (fields are its ``__slots__``)."""
    if hasattr(decoded, "__slots__"):
        return {name: _plain(getattr(decoded, name)) for name in decoded.__slots__}
    if isinstance(decoded, (list, tuple)):
        return [_plain(v) for v in decoded]
    return decoded


def _rosidl_hash(type_name: str) -> str:
    """The RIHS01 hash rosidl generated for ``type_name`` (``share/<pkg>/msg/<Type>.json``)."""
    from ament_index_python.packages import get_package_share_directory

    package, _, name = type_name.split("/")
    generated = json.loads((Path(get_package_share_directory(package)) / "msg"
                            / f"{name}.json").read_text())
    return next(h["hash_string"] for h in generated["type_hashes"]
                if h["type_name"] == type_name)


# --------------------------------------------------------------------------- the checks


def decoded_by_topic(bag_dir) -> dict[str, list]:
    """Every message of the bag decoded by ``mcap`` + ``mcap_ros2`` (the indexed reader foreign
    tools use): topic → [(log time [ns], decoded message)]; the counts per topic must equal
    metadata.yaml's and the summary statistics'."""
    out: dict[str, list] = {}
    with open(_mcap(bag_dir), "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None, "no summary"
        try:
            for _, channel, message, decoded in reader.iter_decoded_messages(
                    log_time_order=False):
                out.setdefault(channel.topic, []).append((message.log_time, decoded))
        except Exception as exc:  # a schema the decoder cannot parse, a payload too short
            raise AssertionError(f"a message does not decode: {exc!r}") from exc
    counts = {topic: len(v) for topic, v in out.items()}
    stats = {summary.channels[cid].topic: n
             for cid, n in summary.statistics.channel_message_counts.items()}
    info = _info(bag_dir)
    listed = {t["topic_metadata"]["name"]: t["message_count"]
              for t in info["topics_with_message_count"]}
    assert counts == listed, f"decoded {counts}, metadata.yaml {listed}"
    assert counts == stats, f"decoded {counts}, summary statistics {stats}"
    assert sum(counts.values()) == info["message_count"] == summary.statistics.message_count
    return out


def check_values(decoded: dict, written: list) -> None:
    """Each decoded message equals the rclpy message serialised into the bag, field by field
    (log times too)."""
    expected: dict[str, list] = {}
    for topic, t_ns, message in written:
        expected.setdefault(topic, []).append((t_ns, msg_samples.ros_to_plain(message)))
    assert sorted(decoded) == sorted(expected)
    for topic, want in expected.items():
        got = [(t_ns, _plain(m)) for t_ns, m in decoded[topic]]
        assert len(got) == len(want), topic
        for i, (g, w) in enumerate(zip(got, want)):
            assert g == w, f"{topic} message {i}: decoded {g}, written {w}"


def check_type_hashes(bag_dir) -> None:
    """Every channel: schema = the topic's type, ``topic_type_hash`` = rosidl's RIHS01 hash,
    and metadata.yaml's ``type_description_hash`` the same."""
    with open(_mcap(bag_dir), "rb") as f:
        summary = make_reader(f).get_summary()
    listed = {t["topic_metadata"]["name"]: t["topic_metadata"]
              for t in _info(bag_dir)["topics_with_message_count"]}
    channels = {c.topic: c for c in summary.channels.values()}
    assert sorted(channels) == sorted(t.name for t in topics.ALL_TOPICS)
    for topic in topics.ALL_TOPICS:
        channel = channels[topic.name]
        schema = summary.schemas[channel.schema_id]
        want = _rosidl_hash(topic.type_name)
        assert (schema.name, schema.encoding, channel.message_encoding) == \
            (topic.type_name, "ros2msg", "cdr"), topic.name
        assert channel.metadata.get("topic_type_hash") == want, \
            f"{topic.name}: topic_type_hash {channel.metadata.get('topic_type_hash')!r}, " \
            f"rosidl {want}"
        assert listed[topic.name]["type_description_hash"] == want, topic.name


def check_file_order_and_crcs(bag_dir) -> int:
    """Read the file record by record (``StreamReader``, CRC validation on): every chunk has a
    non-zero CRC-32 that matches its records, the data-section CRC is non-zero and matches,
    the summary CRC is non-zero and matches the bytes from the summary start through the
    footer; message log times never decrease in file order. Returns the message count."""
    path = _mcap(bag_dir)
    data = path.read_bytes()
    last, n, chunks, data_end, footer = -1, 0, 0, None, None
    try:
        for record in StreamReader(str(path), emit_chunks=True, validate_crcs=True).records:
            inner = [record]
            if isinstance(record, Chunk):
                chunks += 1
                assert record.uncompressed_crc != 0, f"chunk {chunks} has no CRC"
                inner = breakup_chunk(record, validate_crc=True)
            elif isinstance(record, DataEnd):
                data_end = record
            elif isinstance(record, Footer):
                footer = record
            for r in inner:
                if isinstance(r, Message):
                    assert r.log_time >= last, \
                        f"message {n}: log time {r.log_time} after {last} in the file"
                    last, n = r.log_time, n + 1
    except CRCValidationError as exc:
        raise AssertionError(f"{path.name}: {exc}") from exc
    assert chunks > 0 and n > 0
    assert data_end is not None and data_end.data_section_crc != 0, "no data-section CRC"
    assert footer is not None and footer.summary_crc != 0, "no summary CRC"
    # MCAP spec, Footer: the CRC of every byte from the summary's start through the footer's
    # summary_offset_start field (file: ... footer record, summary_crc u32, magic 8 bytes)
    assert footer.summary_crc == zlib.crc32(data[footer.summary_start:len(data) - 12]), \
        "summary CRC does not match"
    return n


def check_against_rosbags_and_ours(bag_dir, decoded: dict) -> None:
    """The first, a middle and the last message of every topic decoded by mcap_ros2 equal
    rosbags' deserialisation and our column reader (``bagio.read_run_bag``)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([Path(bag_dir)]) as reader:
        theirs: dict[str, list] = {}
        for connection, _, raw in reader.messages():
            theirs.setdefault(connection.topic, []).append(
                msg_samples.rosbags_to_plain(reader.deserialize(raw, connection.msgtype)))
    ours = bagio.read_run_bag(bag_dir)
    for topic, messages in decoded.items():
        cols = ours[topic]
        for i in sorted({0, len(messages) // 2, len(messages) - 1}):
            t_ns, message = messages[i]
            plain = _plain(message)
            assert plain == theirs[topic][i], f"{topic} message {i}: rosbags differs"
            assert int(cols.log_time_ns[i]) == t_ns
            stamp = plain["header"]["stamp"] if "header" in plain else plain["clock"]
            assert int(cols["stamp_ns"][i]) == stamp["sec"] * 10**9 + stamp["nanosec"]
            compared = 0
            for field, value in plain.items():
                if isinstance(value, dict) or field not in cols.columns:
                    continue
                if field in cols.counts:  # a sequence: concatenated, lengths in counts
                    start = int(cols.counts[field][:i].sum())
                    row = cols[field][start:start + int(cols.counts[field][i])]
                else:
                    row = cols[field][i]
                assert np.asarray(row).ravel().tolist() == \
                    np.asarray(value).ravel().tolist(), f"{topic}.{field} [{i}]"
                compared += 1
            assert compared >= (0 if topic == topics.CLOCK.name else 1), topic


# --------------------------------------------------------------------------- the run bag


@pytest.mark.slow
def test_every_message_decodes_from_the_schema_in_the_file(bag, written):
    decoded = decoded_by_topic(bag)
    assert sorted(decoded) == sorted(t.name for t in topics.ALL_TOPICS)
    # 3 s: 300 INS samples and truth frames + 1, 150 commands, 30 clock ticks + 1
    assert {t: len(v) for t, v in decoded.items()}[topics.INS.name] == 300
    check_values(decoded, written[1])


@pytest.mark.slow
def test_values_equal_rosbags_and_our_reader(bag):
    check_against_rosbags_and_ours(bag, decoded_by_topic(bag))


@pytest.mark.slow
def test_channels_carry_the_rosidl_type_hash(bag):
    check_type_hashes(bag)


def test_starting_time_and_duration_are_the_files(bag):
    """metadata.yaml's starting_time is the first message's log time (simulation time since
    lift-off, the run's t_start: docs convention) and its duration the span to the last one, as
    the MCAP summary statistics state them."""
    with open(_mcap(bag), "rb") as f:
        stats = make_reader(f).get_summary().statistics
    info = _info(bag)
    assert stats.message_start_time == int(SPAN_S[0] * 1e9)
    assert info["starting_time"]["nanoseconds_since_epoch"] == stats.message_start_time
    assert info["duration"]["nanoseconds"] == stats.message_end_time - stats.message_start_time
    (entry,) = info["files"]
    assert entry["starting_time"]["nanoseconds_since_epoch"] == stats.message_start_time


def test_file_order_and_crcs(bag, written):
    assert check_file_order_and_crcs(bag) == len(written[1])


# --------------------------------------------------------------------------- negative cases


def _rewrite(bag_dir, dst, *, schema_text=None, channel_metadata=None, messages=None,
             crcs=True) -> Path:
    """A copy of the bag with its MCAP file rewritten by mcap's own writer, after optional
    edits: ``schema_text(name, text) -> text``, ``channel_metadata(topic, dict) -> dict``,
    ``messages(list of (topic, log time, publish time, sequence, data)) -> list``;
    ``crcs=False`` writes no CRCs. metadata.yaml and the early run metadata are copied."""
    src = _mcap(bag_dir)
    schemas, channels, metadata, records = {}, {}, [], []
    for record in StreamReader(str(src)).records:
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
        elif isinstance(record, Metadata):
            metadata.append(record)
        elif isinstance(record, Message):
            records.append((channels[record.channel_id].topic, record.log_time,
                            record.publish_time, record.sequence, record.data))
    if messages is not None:
        records = messages(records)
    shutil.copytree(bag_dir, dst)
    out = _mcap(dst)
    out.unlink()
    with open(out, "wb") as f:
        writer = Writer(f, compression=CompressionType.NONE, enable_crcs=crcs,
                        enable_data_crcs=crcs)
        writer.start(profile="ros2", library="test_foreign_readers")
        ids = {}
        for channel in channels.values():
            schema = schemas[channel.schema_id]
            text = schema.data.decode()
            if schema_text is not None:
                text = schema_text(schema.name, text)
            meta = dict(channel.metadata)
            if channel_metadata is not None:
                meta = channel_metadata(channel.topic, meta)
            sid = writer.register_schema(schema.name, schema.encoding, text.encode())
            ids[channel.topic] = writer.register_channel(channel.topic,
                                                         channel.message_encoding, sid, meta)
        for m in metadata:
            writer.add_metadata(m.name, m.metadata)
        for topic, log_time, publish_time, sequence, data in records:
            writer.add_message(ids[topic], log_time, data, publish_time, sequence)
        writer.finish()
    return dst


def _all_checks(bag_dir, written_messages):
    decoded = decoded_by_topic(bag_dir)
    check_values(decoded, written_messages)
    check_against_rosbags_and_ours(bag_dir, decoded)
    check_type_hashes(bag_dir)
    check_file_order_and_crcs(bag_dir)


@pytest.mark.slow
def test_an_unaltered_rewrite_passes_every_check(bag, written, tmp_path):
    """The control for the cases below: mcap's writer reproduces the bag faithfully."""
    _all_checks(_rewrite(bag, tmp_path / "same"), written[1])


def test_a_schema_with_two_fields_swapped_fails(bag, written, tmp_path):
    """The InsMeasurement schema text with pitch_rad and pitch_rate_radps swapped: the bytes
    decode, into the wrong fields — the values check sees it."""
    def swap(name, text):
        if name != topics.INS.type_name:
            return text
        assert "\nfloat64 pitch_rad\n" in text and "\nfloat64 pitch_rate_radps\n" in text
        return (text.replace("\nfloat64 pitch_rad\n", "\nfloat64 @@\n")
                .replace("\nfloat64 pitch_rate_radps\n", "\nfloat64 pitch_rad\n")
                .replace("\nfloat64 @@\n", "\nfloat64 pitch_rate_radps\n"))

    altered = _rewrite(bag, tmp_path / "swapped", schema_text=swap)
    with pytest.raises(AssertionError, match="/vega/ins message 0"):
        check_values(decoded_by_topic(altered), written[1])


def test_a_schema_with_a_narrower_type_fails(bag, written, tmp_path):
    """float64 → float32 in the TvcCommand schema: decoded values no longer the written ones."""
    def narrow(name, text):
        return text.replace("float64", "float32", 1) if name == topics.TVC_CMD.type_name \
            else text

    altered = _rewrite(bag, tmp_path / "narrow", schema_text=narrow)
    with pytest.raises(AssertionError, match="/vega/tvc_cmd|does not decode"):
        check_values(decoded_by_topic(altered), written[1])


@pytest.mark.parametrize("edit", ["missing", "wrong"])
def test_a_missing_or_wrong_type_hash_fails(bag, tmp_path, edit):
    def meta(topic, m):
        if topic == topics.ACTUATOR.name:
            if edit == "missing":
                del m["topic_type_hash"]
            else:
                m["topic_type_hash"] = m["topic_type_hash"][:-1] + (
                    "0" if m["topic_type_hash"][-1] != "0" else "1")
        return m

    altered = _rewrite(bag, tmp_path / edit, channel_metadata=meta)
    with pytest.raises(AssertionError, match="/vega/actuator: topic_type_hash"):
        check_type_hashes(altered)


@pytest.mark.slow
def test_a_dropped_message_fails_the_counts(bag, tmp_path):
    def drop(records):
        i = next(k for k, r in enumerate(records) if r[0] == topics.TVC_CMD.name)
        return records[:i] + records[i + 1:]

    altered = _rewrite(bag, tmp_path / "dropped", messages=drop)
    with pytest.raises(AssertionError, match="metadata.yaml"):
        decoded_by_topic(altered)


def test_a_message_out_of_log_time_order_fails(bag, tmp_path):
    def move(records):
        return records[10:11] + records[:10] + records[11:]

    altered = _rewrite(bag, tmp_path / "moved", messages=move)
    with pytest.raises(AssertionError, match="after"):
        check_file_order_and_crcs(altered)


def test_a_bag_without_crcs_fails(bag, tmp_path):
    altered = _rewrite(bag, tmp_path / "nocrc", crcs=False)
    with pytest.raises(AssertionError, match="no CRC"):
        check_file_order_and_crcs(altered)


def test_a_flipped_bit_in_an_ins_payload_fails(bag, tmp_path):
    """One bit of one /vega/ins message's pitch_rad flipped in the file: the chunk CRC no
    longer matches."""
    from mcap_order import file_messages

    damaged = tmp_path / "flipped"
    shutil.copytree(bag, damaged)
    mcap = _mcap(damaged)
    data = bytearray(mcap.read_bytes())
    payload = [p for t, _, p in file_messages(damaged) if t == topics.INS.name][150]
    at = bytes(data).find(payload)
    assert at > 0 and bytes(data).count(payload) == 1
    offset = bagio.cdr_offsets(topics.INS.type_name, payload)["pitch_rad"]
    data[at + offset] ^= 0x01
    mcap.write_bytes(bytes(data))
    with pytest.raises(AssertionError, match="crc validation failed"):
        check_file_order_and_crcs(damaged)
