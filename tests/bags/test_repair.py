"""A bag whose writer died before closing it: the early run metadata and the chunk flushes keep
what was written, `vega bag repair` rebuilds a complete bag from it, and `vega check` reads it."""

import json
import shutil

import pytest

from fixture_bags import short_run, write_bag
from vega_bags import bagio
from vega_bags.repair import repair_bag, scan_mcap
from vega_cli import cli


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return short_run(tmp_path_factory.mktemp("run"), span_s=(20.0, 25.0))


@pytest.fixture(scope="module")
def bag(run, tmp_path_factory):
    return write_bag(tmp_path_factory.mktemp("bag") / "bag", run)


def _messages(path):
    return [(t, ts, bytes(d)) for t, ts, d in bagio.iter_raw_messages(path)]


def _cut(bag, tmp_path, fraction):
    """A copy of the bag as a killed writer leaves it: MCAP cut at ``fraction`` of its bytes,
    no metadata.yaml, the early run metadata kept."""
    dst = tmp_path / "killed"
    shutil.copytree(bag, dst)
    (dst / "metadata.yaml").unlink()
    mcap = next(dst.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[:int(len(data) * fraction)])
    return dst


@pytest.mark.slow
def test_the_writer_puts_run_metadata_and_chunks_on_disk_early(bag):
    meta = json.loads(bagio.run_metadata_path(bag).read_text())
    assert meta["custom_data"] == bagio.read_run_bag(bag).metadata
    data = next(bag.glob("*.mcap")).read_bytes()
    # one chunk per second of log time (5 s here) + the schemas/channels chunk, not one 1 MiB chunk
    assert data.count(b"\x06") >= 6
    channels, messages, dropped = scan_mcap(data)
    assert dropped == 0 and sorted(channels.values()) == sorted(
        t.name for t in bagio.topics.ALL_TOPICS)


@pytest.mark.slow
@pytest.mark.parametrize("fraction", [0.35, 0.7, 0.999])
def test_repair_recovers_a_prefix_of_every_topic(bag, tmp_path, fraction, capsys):
    killed = _cut(bag, tmp_path, fraction)
    assert cli.main(["check", str(killed)]) == 2
    assert "vega bag repair" in capsys.readouterr().err
    assert cli.main(["bag", "repair", str(killed)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"repaired {killed}") and ".mcap.truncated" in out
    original = _messages(bag)
    got = _messages(killed)
    assert 0 < len(got) <= len(original)
    if fraction < 0.9:
        assert len(got) < len(original)
    else:                       # only the summary was cut: every message is recovered
        assert got == original
    by_topic = {}
    for topic, ts, data in original:
        by_topic.setdefault(topic, []).append((ts, data))
    for topic in by_topic:
        mine = [(ts, d) for t, ts, d in got if t == topic]
        assert mine == by_topic[topic][:len(mine)], topic      # a prefix, bit for bit
    last = max(ts for _, ts, _ in got)
    # at most one flush period (1 s) plus the cut chunk is lost
    assert last >= 20e9 + fraction * 5e9 - 2.5e9
    assert bagio.read_run_bag(killed).metadata == bagio.read_run_bag(bag).metadata
    assert any(killed.glob("*.mcap.truncated"))
    complete = got == original
    assert cli.main(["check", str(killed)]) == (0 if complete else 1)   # readable
    assert "run complete" in capsys.readouterr().out


def test_repair_refuses_what_it_cannot_repair(bag, tmp_path, capsys):
    assert cli.main(["bag", "repair", str(bag)]) == 2
    assert "a closed bag, nothing to repair" in capsys.readouterr().err
    killed = _cut(bag, tmp_path, 0.5)
    bagio.run_metadata_path(killed).unlink()
    assert cli.main(["bag", "repair", str(killed)]) == 2
    assert "no usable run metadata" in capsys.readouterr().err
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "junk.mcap").write_bytes(b"not an mcap file at all")
    bagio.run_metadata_path(junk).write_text(json.dumps({"custom_data": {}}))
    assert cli.main(["bag", "repair", str(junk)]) == 2
    assert "not an MCAP file" in capsys.readouterr().err


def test_metadata_names_the_ros_distribution(bag, tmp_path):
    """metadata.yaml says ros_distro: jazzy (rosbags writes its own name), also after a repair."""
    import yaml

    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy" and info["version"] == 9
    killed = _cut(bag, tmp_path, 0.5)
    repair_bag(killed)
    info = yaml.safe_load((killed / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy"


def _channel_metadata(mcap_bytes):
    """topic → metadata map of every MCAP channel record (a reader of its own: opcode 0x04 at
    the top level or inside an uncompressed chunk, 0x06)."""
    import struct

    def string(buf, pos):
        (n,) = struct.unpack_from("<I", buf, pos)
        return bytes(buf[pos + 4:pos + 4 + n]).decode(), pos + 4 + n

    def records(buf, pos, end):
        while pos + 9 <= end:
            op, length = buf[pos], struct.unpack_from("<Q", buf, pos + 1)[0]
            yield op, buf[pos + 9:pos + 9 + length]
            pos += 9 + length

    found = {}

    def channel(body):
        topic, pos = string(body, 4)
        _, pos = string(body, pos)
        (size,) = struct.unpack_from("<I", body, pos)
        pos, end, meta = pos + 4, pos + 4 + size, {}
        while pos < end:
            key, pos = string(body, pos)
            meta[key], pos = string(body, pos)
        found[topic] = meta

    buf = memoryview(mcap_bytes)
    for op, body in records(buf, 8, len(buf)):
        if op == 0x04:
            channel(body)
        elif op == 0x06:
            compression, at = string(body, 28)
            (size,) = struct.unpack_from("<Q", body, at)
            for inner_op, inner in records(body[at + 8:at + 8 + size], 0, size):
                if inner_op == 0x04:
                    channel(inner)
    return found


@pytest.mark.slow
def test_channels_carry_the_rosidl_type_hash(bag):
    """Every MCAP channel has ``topic_type_hash`` = the RIHS01 hash rosidl generated for its
    type (the installed ``share/<pkg>/msg/<Type>.json``), as Jazzy's rosbag2 writes it."""
    from pathlib import Path

    from ament_index_python.packages import get_package_share_directory

    meta = _channel_metadata(next(bag.glob("*.mcap")).read_bytes())
    assert sorted(meta) == sorted(t.name for t in bagio.topics.ALL_TOPICS)
    for topic in bagio.topics.ALL_TOPICS:
        package, _, name = topic.type_name.split("/")
        generated = json.loads((Path(get_package_share_directory(package)) / "msg"
                                / f"{name}.json").read_text())
        want = next(h["hash_string"] for h in generated["type_hashes"]
                    if h["type_name"] == topic.type_name)
        assert meta[topic.name]["topic_type_hash"] == want, topic.name
        assert "offered_qos_profiles" in meta[topic.name]


def test_a_flipped_bit_is_found_by_the_chunk_crc(bag, tmp_path, capsys):
    """Chunks carry their CRC-32 (rosbags' writer leaves 0 = none): one bit flipped in a
    message payload inside the bag makes `vega check` refuse it, and `vega bag repair` too."""
    import struct

    data = bytearray(next(bag.glob("*.mcap")).read_bytes())
    # the second chunk record (the first holds only the schemas and channels): CRC set
    pos, seen = 8, 0
    while True:
        if data[pos] == 0x06:
            seen += 1
            if seen == 2:
                break
        pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    assert struct.unpack_from("<I", data, pos + 9 + 24)[0] != 0
    damaged = tmp_path / "damaged"
    shutil.copytree(bag, damaged)
    mcap = next(damaged.glob("*.mcap"))
    # a byte of the last message written to that chunk (its payload ends the chunk's records)
    length = struct.unpack_from("<Q", data, pos + 1)[0]
    data[pos + 9 + length - 3] ^= 0x10
    mcap.write_bytes(bytes(data))
    assert cli.main(["check", str(damaged)]) == 2
    assert "data section CRC" in capsys.readouterr().err       # the file's CRC finds it first
    (damaged / "metadata.yaml").unlink()
    assert cli.main(["bag", "repair", str(damaged)]) == 2
    assert "fail their CRC-32" in capsys.readouterr().err


def test_data_and_summary_crcs_are_written_and_checked(bag, tmp_path, capsys):
    """The MCAP DataEnd and Footer records carry the data-section and
    summary CRC-32 (rosbags writes 0, "not computed"); a flipped bit in the summary (which no
    chunk CRC covers) makes `vega check` refuse the bag in one line."""
    import struct

    mcap = next(bag.glob("*.mcap"))
    data = mcap.read_bytes()
    end_at, data_crc, data_now, footer_at, summary_crc, summary_now = \
        bagio._section_crcs(data)
    assert data_crc == data_now != 0 and summary_crc == summary_now != 0
    summary_start = struct.unpack_from("<Q", data, footer_at + 9)[0]
    assert end_at + 13 == summary_start < footer_at
    damaged = tmp_path / "damaged"
    shutil.copytree(bag, damaged)
    broken = bytearray(data)
    broken[summary_start + 20] ^= 0x01
    next(damaged.glob("*.mcap")).write_bytes(bytes(broken))
    assert cli.main(["check", str(damaged)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "summary CRC" in err
