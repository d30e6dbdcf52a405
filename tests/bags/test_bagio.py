"""Run bags (vega_bags.bagio): writer, reader, metadata and the one-line errors.

Messages are rclpy messages serialised by rclpy (the bytes a recorder receives); the bag is
read back by our reader and by plain rosbags. The run metadata helpers (git revision, file
SHA-256, :func:`vega_bags.bagio.run_metadata`) are checked against a throw-away git repository
made here (its commit read from ``.git/HEAD`` and the ref file, not through ``git rev-parse``),
hashlib's SHA-256 of the bytes and the documented metadata keys.
"""

import hashlib
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import serialize_message

import msg_samples
from vega_bus import qos, topics
from vega_bags import bagio
from vega_bags.bagio import (META_CONTROLLER_TABLE, META_CONTROLLER_TABLE_SHA256,
                             META_GIT_REVISION, META_GUIDANCE_REFERENCE,
                             META_GUIDANCE_REFERENCE_SHA256, META_SCENARIO, META_SCENARIO_YAML,
                             META_SEED, file_sha256, git_revision, run_metadata)

TOPIC_OF = {"InsMeasurement": topics.INS.name, "TvcCommand": topics.TVC_CMD.name,
            "StepDiagnostics": topics.DIAGNOSTICS.name,
            "ActuatorState": topics.ACTUATOR.name, "VehicleState": topics.TRUTH.name}
META = {bagio.META_SCENARIO: "thesis", bagio.META_SCENARIO_YAML: "name: thesis\nseed: 7\n",
        bagio.META_SEED: 7, bagio.META_CONTROLLER_TABLE: "/x/table.npz",
        bagio.META_CONTROLLER_TABLE_SHA256: "0" * 64, bagio.META_GIT_REVISION: "abc"}


def _ns(stamp):
    return stamp["sec"] * 1_000_000_000 + stamp["nanosec"]


@pytest.fixture(scope="module")
def sample_bag(tmp_path_factory):
    """One sample of each vega message (rclpy-serialised) at its stamp, plus two /clock."""
    from rosgraph_msgs.msg import Clock

    path = tmp_path_factory.mktemp("bag") / "run"
    with bagio.RunBagWriter(path, META) as bag:
        for name in msg_samples.TYPE_NAMES:
            bag.write(TOPIC_OF[name], _ns(msg_samples.SAMPLES[name]["header"]["stamp"]),
                      serialize_message(msg_samples.to_ros(name)))
        for t_ns in (5_000_000, 5_010_000):
            clock = Clock()
            clock.clock.sec, clock.clock.nanosec = divmod(t_ns, 1_000_000_000)
            bag.write(topics.CLOCK.name, t_ns, serialize_message(clock))
    return path


@pytest.mark.slow
def test_fields_read_back_equal(sample_bag):
    """Every field of every sample comes back in its column, with the log time = stamp."""
    bag = bagio.read_run_bag(sample_bag)
    assert set(bag.topics) == {t.name for t in topics.ALL_TOPICS}
    for name, sample in msg_samples.SAMPLES.items():
        cols = bag[TOPIC_OF[name]]
        assert len(cols) == 1
        assert cols.log_time_ns.tolist() == [_ns(sample["header"]["stamp"])]
        assert cols["stamp_ns"].tolist() == [_ns(sample["header"]["stamp"])]
        for field, value in sample.items():
            if field == "header":
                continue
            if field == "sample_stamp":
                assert cols["sample_stamp_ns"].tolist() == [_ns(value)]
            elif isinstance(value, list):
                assert cols[field].ravel().tolist() == value, field
                if field in cols.counts:
                    assert cols.counts[field].tolist() == [len(value)]
            else:
                assert cols[field].tolist() == [value], field
    assert bag[topics.CLOCK.name]["stamp_ns"].tolist() == [5_000_000, 5_010_000]
    assert bag.metadata == {k: str(v) for k, v in META.items()}


def test_plain_rosbags_reads_the_bag(sample_bag):
    """rosbags alone (typestore from the message definitions stored in the bag) decodes it."""
    from rosbags.highlevel import AnyReader

    with AnyReader([sample_bag]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == \
            {t.name: t.type_name for t in topics.ALL_TOPICS}
        decoded = {c.topic: reader.deserialize(raw, c.msgtype)
                   for c, _, raw in reader.messages() if c.topic != topics.CLOCK.name}
    for name, sample in msg_samples.SAMPLES.items():
        assert msg_samples.rosbags_to_plain(decoded[TOPIC_OF[name]]) == sample


def test_metadata_and_qos_in_metadata_yaml(sample_bag):
    """metadata.yaml: version 9, MCAP, custom_data, the offered QoS and the RIHS01 hashes."""
    import yaml

    info = yaml.safe_load((sample_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["custom_data"][bagio.META_SCENARIO_YAML] == META[bagio.META_SCENARIO_YAML]
    by_name = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    ins = by_name[topics.INS.name]["topic_metadata"]
    assert ins["offered_qos_profiles"][0]["reliability"] == "reliable"
    assert ins["offered_qos_profiles"][0]["depth"] == topics.DATA_QUEUE_DEPTH
    assert ins["type_description_hash"] == \
        bagio.vega_typestore().hash_rihs01(topics.INS.type_name)
    assert by_name[topics.CLOCK.name]["message_count"] == 2
    clock_qos = by_name[topics.CLOCK.name]["topic_metadata"]["offered_qos_profiles"][0]
    assert clock_qos["depth"] == qos.clock_qos().depth


def test_writer_closes_on_error_and_keeps_the_bag_readable(tmp_path):
    path = tmp_path / "crashed"
    data = serialize_message(msg_samples.to_ros("InsMeasurement"))
    with pytest.raises(RuntimeError, match="boom"):
        with bagio.RunBagWriter(path, META) as bag:
            bag.write(topics.INS.name, 1, data)
            bag.write(topics.INS.name, 2, data)
            raise RuntimeError("boom")
    assert bagio.read_run_bag(path)[topics.INS.name].log_time_ns.tolist() == [1, 2]


def test_writer_rejects_bad_use(tmp_path):
    meta = dict(META)
    del meta[bagio.META_GIT_REVISION]
    with pytest.raises(ValueError, match="missing vega.git_revision"):
        bagio.RunBagWriter(tmp_path / "a", meta)
    with pytest.raises(ValueError, match="must be strings"):
        bagio.RunBagWriter(tmp_path / "a", {**META, "x": [1]})
    with bagio.RunBagWriter(tmp_path / "b", META) as bag:
        with pytest.raises(ValueError, match="not a topic of the graph"):
            bag.write("/chatter", 0, b"")
    with pytest.raises(FileExistsError, match="exists already"):
        bagio.RunBagWriter(tmp_path / "b", META).open()


def test_run_metadata(tmp_path):
    table = tmp_path / "t.npz"
    table.write_bytes(b"abc")
    meta = bagio.run_metadata("gust", "name: gust\n", 3, table, git_rev="r1",
                              extra={"vega.plant": "linear"})
    assert meta[bagio.META_CONTROLLER_TABLE_SHA256] == \
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"  # SHA-256("abc")
    assert meta[bagio.META_SEED] == "3" and meta["vega.plant"] == "linear"
    assert set(bagio.REQUIRED_METADATA) <= set(meta)
    assert bagio.git_revision(tmp_path) == "unknown"


# ------------------------------------------------- run metadata: git revision, file digest
def _git(repo, *args):
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@localhost",
                    "-c", "commit.gpgsign=false", *args], cwd=repo, check=True,
                   capture_output=True)


def _head(repo: Path) -> str:
    """The commit of HEAD read from the files of .git (no git command)."""
    head = (repo / ".git" / "HEAD").read_text().strip()
    assert head.startswith("ref: ")
    return (repo / ".git" / head[5:]).read_text().strip()


@pytest.fixture
def repo(tmp_path):
    r = tmp_path / "repo"
    r.mkdir()
    _git(r, "init", "-q")
    (r / "a.txt").write_text("one\n")
    _git(r, "add", "a.txt")
    _git(r, "commit", "-q", "-m", "first")
    return r


def test_clean_repository_gives_its_commit(repo):
    sha = _head(repo)
    assert re.fullmatch(r"[0-9a-f]{40}", sha)
    assert git_revision(repo) == sha
    # untracked files do not make it dirty
    (repo / "new.txt").write_text("untracked\n")
    assert git_revision(repo) == sha


def test_modified_tracked_file_is_dirty(repo):
    (repo / "a.txt").write_text("two\n")
    assert git_revision(repo) == _head(repo) + "+dirty"
    assert git_revision(str(repo)) == _head(repo) + "+dirty"


def test_outside_git_is_unknown(tmp_path):
    plain = tmp_path / "plain"
    plain.mkdir()
    assert git_revision(plain) == "unknown"


def test_status_failing_is_unknown(repo):
    """A corrupt index: `git rev-parse HEAD` still works, `git status` fails → unknown."""
    (repo / ".git" / "index").write_bytes(b"garbage, not an index")
    assert git_revision(repo) == "unknown"


def test_default_is_the_package_checkout():
    rev = git_revision()
    assert rev == "unknown" or re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", rev)
    assert rev != "unknown"          # the tests run from a git checkout


def test_file_sha256_is_hashlib_of_the_bytes(tmp_path):
    data = bytes(range(256)) * 9000          # 2.3 MB: more than one 1 MiB block
    f = tmp_path / "blob"
    f.write_bytes(data)
    assert file_sha256(f) == hashlib.sha256(data).hexdigest()
    assert file_sha256(str(f)) == hashlib.sha256(data).hexdigest()


def test_run_metadata_keys_and_values(tmp_path, repo):
    table = tmp_path / "table.npz"
    table.write_bytes(b"table bytes")
    guide = tmp_path / "guide.csv"
    guide.write_bytes(b"guide bytes")
    meta = run_metadata("nominal", "name: nominal\n", 7, table, git_rev="abc123")
    assert meta == {
        META_SCENARIO: "nominal",
        META_SCENARIO_YAML: "name: nominal\n",
        META_SEED: "7",
        META_CONTROLLER_TABLE: str(table.resolve()),
        META_CONTROLLER_TABLE_SHA256: hashlib.sha256(b"table bytes").hexdigest(),
        META_GIT_REVISION: "abc123",
        META_GUIDANCE_REFERENCE: "none",
    }
    meta = run_metadata("n", "y", 1, str(table), git_rev="r", guidance_reference=str(guide),
                        extra={"vega.plant": "nonlinear", "vega.n": 3})
    assert meta[META_GUIDANCE_REFERENCE] == str(guide.resolve())
    assert meta[META_GUIDANCE_REFERENCE_SHA256] == hashlib.sha256(b"guide bytes").hexdigest()
    assert meta["vega.plant"] == "nonlinear" and meta["vega.n"] == "3"
    # default revision: the package checkout's
    assert run_metadata("n", "y", 1, table)[META_GIT_REVISION] == git_revision()


def test_repository_without_a_commit_is_unknown(tmp_path):
    """`git rev-parse HEAD` fails (prints "HEAD" on stdout) while `git status` works."""
    r = tmp_path / "empty"
    r.mkdir()
    _git(r, "init", "-q")
    assert git_revision(r) == "unknown"


# ----------------------------------------------------------------------------- bad bags
def _one_line_error(path, match):
    with pytest.raises(bagio.BagError, match=match) as info:
        bagio.read_run_bag(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_missing_and_not_a_bag(tmp_path):
    _one_line_error(tmp_path / "nope", "no such file or directory")
    (tmp_path / "file").write_text("x")
    _one_line_error(tmp_path / "file", "not a rosbag2 directory")
    _one_line_error(tmp_path, "no metadata.yaml")


def test_unclosed_bag(sample_bag, tmp_path):
    import shutil

    path = tmp_path / "unclosed"
    shutil.copytree(sample_bag, path)
    (path / "metadata.yaml").unlink()
    _one_line_error(path, "no metadata.yaml next to its MCAP file: the bag was not closed")


def test_truncated_mcap(sample_bag, tmp_path):
    import shutil

    path = tmp_path / "truncated"
    shutil.copytree(sample_bag, path)
    (mcap,) = path.glob("*.mcap")
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    _one_line_error(path, "unreadable|corrupt")


def test_garbage_metadata(sample_bag, tmp_path):
    import shutil

    path = tmp_path / "garbage"
    shutil.copytree(sample_bag, path)
    (path / "metadata.yaml").write_text("rosbag2_bagfile_information: [1, 2\n")
    _one_line_error(path, "unreadable")


def _foreign(path, topic, msgtype, message):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(topic, msgtype, typestore=store)
        writer.write(conn, 1, store.serialize_cdr(message, msgtype))


def test_foreign_bags(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    String = get_typestore(Stores.ROS2_JAZZY).types["std_msgs/msg/String"]
    _foreign(tmp_path / "chatter", "/chatter", "std_msgs/msg/String", String(data="hi"))
    _one_line_error(tmp_path / "chatter", "foreign bag: none of the vega topics.*/chatter")
    _foreign(tmp_path / "wrongtype", topics.INS.name, "std_msgs/msg/String", String(data="x"))
    _one_line_error(tmp_path / "wrongtype",
                    "foreign bag: topic /vega/ins has type std_msgs/msg/String")


def test_iter_raw_messages_gives_the_recorded_bytes(sample_bag):
    got = list(bagio.iter_raw_messages(sample_bag, {topics.TVC_CMD.name}))
    assert len(got) == 1
    topic, t_ns, data = got[0]
    assert topic == topics.TVC_CMD.name and t_ns == 42_012_000_000
    decoded = bagio.vega_typestore().deserialize_cdr(data, topics.TVC_CMD.type_name)
    assert decoded.seq == 2_500 and decoded.status == 4
    assert np.isfinite(decoded.deflection_cmd_rad)
    ((_, _, data),) = bagio.iter_raw_messages(sample_bag, {topics.DIAGNOSTICS.name})
    decoded = bagio.vega_typestore().deserialize_cdr(data, topics.DIAGNOSTICS.type_name)
    assert math.isclose(decoded.compute_time_s, 1.25e-4) and decoded.seq == 2_500


@pytest.mark.slow
def test_fast_reader_equals_rosbags_deserialiser(tmp_path):
    """The numpy column reader gives what rosbags' deserialiser gives (values, dtypes, shapes),
    and messages of differing layouts (frame_id lengths) fall back to the deserialiser."""
    from fixture_bags import short_run, write_bag

    run = short_run(tmp_path, span_s=(30.0, 30.5))

    def vary_frame_ids(messages):
        for k, i in enumerate(i for i, m in enumerate(messages) if m[0] == topics.INS.name):
            messages[i][2].header.frame_id = "b" * (k % 3)

    store = bagio.vega_typestore()
    for name, mutate in (("same", None), ("varied", vary_frame_ids)):
        path = write_bag(tmp_path / name, run, mutate)
        bag = bagio.read_run_bag(path)
        raw = {}
        for topic, _, data in bagio.iter_raw_messages(path):
            raw.setdefault(topic, []).append(bytes(data))
        for topic, cols in bag.topics.items():
            msgs = [store.deserialize_cdr(d, cols.type_name) for d in raw[topic]]
            want, want_counts = bagio._columns_of(store, cols.type_name, msgs)
            assert want.keys() == cols.columns.keys(), topic
            for key, value in want.items():
                got = cols.columns[key]
                assert got.dtype == value.dtype and got.shape == value.shape, (topic, key)
                assert np.array_equal(got, value), (topic, key)
            assert {k: v.tolist() for k, v in want_counts.items()} == \
                {k: v.tolist() for k, v in cols.counts.items()}
        if name == "varied":
            with pytest.raises(bagio._NotFlat):
                bagio._fast_columns(store, topics.INS.type_name, raw[topics.INS.name])


def test_fast_message_write_gives_rosbags_bytes(tmp_path, monkeypatch):
    """RunBagWriter's own Message-record write (one struct.pack) against rosbags' McapWriter
    and Writer ``write`` (BytesIO per record, min/max bookkeeping), restored on the same class
    for a second bag of the same messages: the MCAP files and metadata.yaml are identical —
    record bytes, chunk indexes, statistics, start time and duration (a message at t = 0 and
    out-of-order log times included; a chunk closed by size too)."""
    from rosbags.rosbag2.storage_mcap import McapWriter
    from rosbags.rosbag2.writer import Writer

    rng = np.random.default_rng(11)
    data = [serialize_message(msg_samples.to_ros(name)) for name in msg_samples.TYPE_NAMES]
    messages = [(TOPIC_OF[msg_samples.TYPE_NAMES[i % len(data)]], int(t), data[i % len(data)])
                for i, t in enumerate([0, 7, 3] + sorted(rng.integers(10, 3_000_000_000, 9000)))]

    def write(parent):
        path = parent / "run"                   # the MCAP file names itself in its metadata
        with bagio.RunBagWriter(path, META) as bag:
            for topic, t, payload in messages:
                bag.write(topic, t, payload)
        return (path / "run.mcap").read_bytes(), (path / "metadata.yaml").read_text()

    fast = write(tmp_path / "fast")
    cls = bagio._writer_class()
    monkeypatch.setattr(cls, "write", Writer.write)
    monkeypatch.setattr(cls.STORAGE_PLUGINS[next(k for k in cls.STORAGE_PLUGINS
                                                 if cls.STORAGE_PLUGINS[k].__name__ ==
                                                 "_McapWriter")], "write", McapWriter.write)
    reference = write(tmp_path / "reference")
    assert fast[1] == reference[1]
    assert len(fast[0]) > 2**20                     # more than one size-closed chunk
    assert fast[0] == reference[0]
