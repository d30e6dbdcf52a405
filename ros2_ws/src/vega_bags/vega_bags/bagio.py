"""Run bags: the one typestore, the writer the recorder uses, and the reader of the checks.

A *run bag* is one rosbag2 directory (``metadata.yaml`` + one MCAP file) written with
``rosbags`` the way Jazzy writes its own bags (format version 9, MCAP storage), holding:

* the topics of :mod:`vega_bus.topics` (``/vega/truth``, ``/vega/ins``, ``/vega/tvc_cmd``,
  ``/vega/actuator``, ``/clock``, ``/vega/diagnostics``) with the QoS the publishers offer;
* every message as the raw CDR bytes the recorder received, with log time = the message's
  sim-time stamp in nanoseconds (``header.stamp``; ``clock`` for ``/clock``), in the file in
  (log time, :data:`vega_bus.topics.RECORD_ORDER`, seq) order (:class:`RunBagWriter` callers
  write in that order: the recorder through its :class:`vega_bags.recorder.Reorder` buffer, the
  in-process bags sorted): two runs of one scenario and seed give the same file order;
* custom metadata (rosbag2 ``custom_data``, string → string) with at least the keys of
  :data:`REQUIRED_METADATA`: scenario name and YAML text, seed, controller-table path and
  SHA-256, git revision (:func:`run_metadata` builds them).

Pieces:

* :func:`vega_typestore` — the typestore (Jazzy's plus the vega_msgs types registered from
  the installed ``.msg`` files found through the ament index); every reader, writer and
  replay tool uses this one.
* :class:`RunBagWriter` — open → :meth:`~RunBagWriter.write` (topic, log time, raw bytes) →
  close; a context manager that closes the bag on error too, so that what was written stays
  readable.
* :func:`cdr_offsets` — where each field of a raw message sits (the computed CDR layout the
  fast reader uses; the recorder reads stamps and sequence numbers there).
* :func:`read_run_bag` — the whole bag as per-topic numpy columns (:class:`TopicColumns`) plus
  the custom metadata (:class:`RunBag`). A missing, corrupt or foreign bag (no vega topic, or
  a vega topic with another type) raises :class:`BagError` (a
  :class:`vega_core.errors.BadFile`) with one line.

Columns (:class:`TopicColumns`): ``log_time_ns``; ``stamp_ns`` (header stamp; ``clock`` of
/clock); ``<name>_ns`` for other ``builtin_interfaces/Time`` fields (``sample_stamp_ns``);
scalars as (N,) arrays (``seq``, ``pitch_rad``, …); fixed-size arrays as (N, k); variable-size
arrays (the actuator's sub-frame samples) flattened in message order, with their per-message
lengths in :attr:`TopicColumns.counts`. ``header.frame_id`` is not kept.
"""

from __future__ import annotations

import hashlib
import json
import struct
import subprocess
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np

from vega_core.documents import read_text
from vega_core.errors import BadFile, one_line

from vega_bus import qos, topics
from vega_bus.timing import NS_PER_S

__all__ = ["BagError", "META_SCENARIO", "META_SCENARIO_YAML", "META_SEED",
           "META_CONTROLLER_TABLE", "META_CONTROLLER_TABLE_SHA256", "META_GIT_REVISION",
           "META_GUIDANCE_REFERENCE", "META_GUIDANCE_REFERENCE_SHA256",
           "RUN_METADATA_FILE", "FLUSH_PERIOD_NS", "run_metadata_path",
           "REQUIRED_METADATA", "vega_typestore", "topic_qos", "run_metadata",
           "git_revision", "file_sha256", "RunBagWriter", "TopicColumns", "RunBag",
           "read_run_bag", "iter_raw_messages", "cdr_offsets"]

# custom_data keys (rosbag2 metadata; values are strings)
META_SCENARIO = "vega.scenario"
META_SCENARIO_YAML = "vega.scenario_yaml"
META_SEED = "vega.seed"
META_CONTROLLER_TABLE = "vega.controller_table"
META_CONTROLLER_TABLE_SHA256 = "vega.controller_table_sha256"
META_GIT_REVISION = "vega.git_revision"
META_GUIDANCE_REFERENCE = "vega.guidance_reference"
META_GUIDANCE_REFERENCE_SHA256 = "vega.guidance_reference_sha256"
"""The guidance reference the controller flew (absolute path, or "none"; a bag without the key
was recorded before the guidance existed: flown with none) and its SHA-256."""
REQUIRED_METADATA = (META_SCENARIO, META_SCENARIO_YAML, META_SEED, META_CONTROLLER_TABLE,
                     META_CONTROLLER_TABLE_SHA256, META_GIT_REVISION)
"""custom_data keys every run bag carries (the writer refuses to open without them)."""

_VEGA_TYPES = tuple(sorted({t.type_name for t in topics.ALL_TOPICS
                            if t.type_name.startswith("vega_msgs/")}))

ROS_DISTRO = "jazzy"
"""``ros_distro`` of the bags' metadata.yaml."""
RUN_METADATA_FILE = "vega_run_metadata.json"
"""The run metadata, written beside the MCAP file when the bag is opened (crash safety)."""
FLUSH_PERIOD_NS = 1_000_000_000
"""Log time between two chunk flushes of :class:`RunBagWriter` (1 s)."""


@lru_cache(maxsize=1)
def _writer_class():
    """rosbags' rosbag2 writer whose MCAP channels also carry ``topic_type_hash`` (the RIHS01
    type hash, as Jazzy's rosbag2 MCAP plugin writes it and ``ros2 bag reindex`` reads it; the
    rosbags writer puts it in metadata.yaml only) and whose chunks carry their CRC-32. Built on
    rosbags' MCAP writer (pinned version; tests/bags/test_repair.py reads the channel records
    and checks the CRCs)."""
    import zlib
    from io import BytesIO

    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.storage_mcap import (Channel, McapWriter, write_channel,
                                              write_string)

    class _McapWriter(McapWriter):
        def close_chunk(self) -> None:
            # the chunk record's CRC-32 of its uncompressed records (rosbags leaves it 0: "no
            # CRC"); rosbags' reader checks a non-zero one, so vega check finds a flipped bit.
            # Record layout: opcode u8, length u64, start u64, end u64, size u64, crc u32.
            start = self.bio.tell()
            crc = zlib.crc32(self.chunk.bio.getvalue())
            super().close_chunk()
            end = self.bio.tell()
            self.bio.seek(start + 1 + 8 + 3 * 8)
            self.bio.write(crc.to_bytes(4, "little"))
            self.bio.seek(end)

        def add_connection(self, connection, offered_qos_profiles: str) -> None:
            metadata = BytesIO()
            for key, value in (("offered_qos_profiles", offered_qos_profiles),
                               ("topic_type_hash", connection.digest)):
                write_string(metadata, key)
                write_string(metadata, value)
            self.channels.append(Channel(connection.id, connection.msgtype, connection.topic,
                                         connection.ext.serialization_format,
                                         metadata.getvalue()))
            self.channel_stats[connection.id] = 0
            write_channel(self.chunk.bio, self.channels[-1], self.schemas)

        def write(self, connection, timestamp: int, data) -> None:
            # rosbags' McapWriter.write, the same bytes (a Message record: opcode 0x05, length,
            # channel id u16, sequence u32 = 0, log time u64, publish time u64 = log time, data)
            # in one struct.pack instead of a BytesIO per message: ≈ 5 → 2 µs (the recorder
            # writes ≈ 41 000 messages a flight)
            if timestamp < self.message_start_time:
                self.message_start_time = timestamp
            if timestamp > self.message_end_time:
                self.message_end_time = timestamp
            cid = connection.id
            self.channel_stats[cid] += 1
            chunk = self.chunk
            if timestamp < chunk.message_start_time:
                chunk.message_start_time = timestamp
            if timestamp > chunk.message_end_time:
                chunk.message_end_time = timestamp
            bio = chunk.bio
            chunk.msgs[cid].append((timestamp, bio.tell()))
            bio.write(_MESSAGE_HEAD.pack(0x05, 22 + len(data), cid, 0, timestamp, timestamp))
            bio.write(data)
            if bio.tell() > 2**20:
                self.close_chunk()

    class _Writer(Writer):
        STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _McapWriter}

        def write(self, connection, timestamp: int, data) -> None:
            # rosbags' Writer.write without its per-message checks (RunBagWriter.write makes
            # them: the bag open, the topic one of its connections; no per-message compression)
            self.storage.write(connection, timestamp, data)
            self.counts[connection.id] += 1
            if timestamp < self.min_timestamp:
                self.min_timestamp = timestamp
            if timestamp > self.max_timestamp:
                self.max_timestamp = timestamp

    return _Writer


_MAGIC = b"\x89MCAP0\r\n"
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")   # opcode 0x05, length, channel, sequence, times
_FOOTER = struct.Struct("<BQQQI")      # opcode 0x02, length 20, summary_start, offset_start, crc
_DATA_END = struct.Struct("<BQI")      # opcode 0x0F, length 4, data_section_crc


def _section_crcs(data: bytes) -> tuple[int, int, int, int, int, int] | None:
    """(DataEnd offset, stored data CRC, computed data CRC, footer offset, stored summary CRC,
    computed summary CRC) of a closed MCAP file (MCAP specification, "DataEnd" and "Footer":
    the data-section CRC covers every byte from the file's start to the DataEnd record, the
    summary CRC every byte from the summary's start through the footer's
    ``summary_offset_start``); None if the file does not end in a footer and a DataEnd
    record where the footer says."""
    import zlib

    footer_at = len(data) - len(_MAGIC) - _FOOTER.size
    if footer_at < len(_MAGIC) or data[-len(_MAGIC):] != _MAGIC:
        return None
    op, length, summary_start, _, summary_crc = _FOOTER.unpack_from(data, footer_at)
    end_at = (summary_start or footer_at) - _DATA_END.size
    if op != 0x02 or length != 20 or end_at < len(_MAGIC):
        return None
    op, length, data_crc = _DATA_END.unpack_from(data, end_at)
    if op != 0x0F or length != 4:
        return None
    summary_from = summary_start or footer_at
    return (end_at, data_crc, zlib.crc32(data[:end_at]), footer_at, summary_crc,
            zlib.crc32(data[summary_from:footer_at + _FOOTER.size - 4]))


def write_section_crcs(mcap: Path) -> None:
    """Write the data-section and summary CRCs into a closed MCAP file (rosbags leaves both
    0, "not computed")."""
    data = mcap.read_bytes()
    found = _section_crcs(data)
    if found is None:
        raise BagError(f"bag file {mcap}: no MCAP footer after closing")
    end_at, _, data_crc, footer_at, _, _ = found
    with open(mcap, "r+b") as f:
        f.seek(end_at + 9)
        f.write(data_crc.to_bytes(4, "little"))
    data = mcap.read_bytes()
    summary_crc = _section_crcs(data)[5]
    with open(mcap, "r+b") as f:
        f.seek(footer_at + _FOOTER.size - 4)
        f.write(summary_crc.to_bytes(4, "little"))


def check_section_crcs(path: Path) -> None:
    """Raise :class:`BagError` (one line) if a non-zero data-section or summary CRC of the
    bag's MCAP files does not match their bytes (0 = not computed: nothing to check)."""
    for mcap in sorted(path.glob("*.mcap")):
        found = _section_crcs(mcap.read_bytes())
        if found is None:
            continue        # rosbags' reader names a file without a footer
        _, data_crc, data_now, _, summary_crc, summary_now = found
        for what, stored, now in (("data section", data_crc, data_now),
                                  ("summary", summary_crc, summary_now)):
            if stored and stored != now:
                raise BagError(f"bag {path}: corrupt data ({mcap.name}: {what} CRC "
                               f"{stored:08x} stored, {now:08x} computed)")


def run_metadata_path(bag_dir: str | Path) -> Path:
    """Path of the early run-metadata file of a bag directory."""
    return Path(bag_dir) / RUN_METADATA_FILE


class BagError(BadFile):
    """A bag that cannot be used: missing, corrupt, foreign or not a run bag (one line)."""


# ----------------------------------------------------------------------------- typestore
def _msg_dir() -> Path:
    """``share/vega_msgs/msg`` of the installed vega_msgs (ament index)."""
    try:
        from ament_index_python.packages import (PackageNotFoundError,
                                                 get_package_share_directory)
    except ImportError as exc:  # pragma: no cover - the environment always has it
        raise BagError(f"cannot locate vega_msgs: {exc}") from None
    try:
        return Path(get_package_share_directory("vega_msgs")) / "msg"
    except (PackageNotFoundError, LookupError, OSError) as exc:
        raise BagError(f"cannot locate the vega_msgs message files in the ament index "
                       f"({exc}); run `make setup` and use the project environment "
                       f"(vega-env)") from None


@lru_cache(maxsize=1)
def vega_typestore():
    """rosbags' Jazzy typestore with the vega_msgs types registered (built once, cached).

    The definitions are the installed ``share/vega_msgs/msg/*.msg`` files (the same files
    rosidl generated the rclpy classes from: identical CDR layout and RIHS01 hash).

    Raises
    ------
    BagError
        If vega_msgs is not installed or a message file is unreadable.
    """
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    store = get_typestore(Stores.ROS2_JAZZY)
    msg_dir = _msg_dir()
    types: dict[str, Any] = {}
    for type_name in _VEGA_TYPES:
        path = msg_dir / f"{type_name.rsplit('/', 1)[1]}.msg"
        text = read_text(path, "message definition", BagError)
        types.update(get_types_from_msg(text, type_name))
    store.register(types)
    return store


def topic_qos(topic: topics.Topic):
    """The QoS the publishers of ``topic`` offer (:func:`vega_bus.qos.data_qos` /
    :func:`~vega_bus.qos.clock_qos`), as a rosbags ``Qos`` for the bag's metadata."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    profile = qos.clock_qos() if topic is topics.CLOCK else qos.data_qos()
    # "infinite" deadline/lifespan/lease as Jazzy's recorder stores what the graph reports
    # for rclpy's default profile (RMW_DURATION_INFINITE = 2^63 - 1 ns)
    infinite = QosTime(9_223_372_036, 854_775_807)
    return Qos(QosHistory[profile.history.name], profile.depth,
               QosReliability[profile.reliability.name],
               QosDurability[profile.durability.name], infinite, infinite,
               QosLiveliness.AUTOMATIC, infinite, False)


# ----------------------------------------------------------------------------- metadata
def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def git_revision(where: str | Path | None = None) -> str:
    """Commit of the working tree holding ``where`` (default: this package's source).

    ``<sha>``; ``<sha>+dirty`` if tracked files differ from it; ``unknown`` outside git.
    """
    cwd = Path(where) if where is not None else Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=cwd, capture_output=True, text=True, timeout=30,
                               check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return f"{sha}+dirty" if dirty else sha


def run_metadata(scenario_name: str, scenario_yaml: str, seed: int,
                 controller_table: str | Path, *, git_rev: str | None = None,
                 guidance_reference: str | Path | None = None,
                 extra: Mapping[str, str] | None = None) -> dict[str, str]:
    """The custom metadata of a run bag (:data:`REQUIRED_METADATA` keys, plus ``extra``).

    Parameters
    ----------
    scenario_name, scenario_yaml
        Scenario name and the full YAML text it was loaded from.
    seed
        Scenario seed in force.
    controller_table
        Path of the controller table file (its SHA-256 is computed here).
    git_rev
        Git revision (default: :func:`git_revision`).
    guidance_reference
        Path of the guidance reference the controller flies (its SHA-256 is computed here),
        or None for none.
    extra
        More string entries (e.g. ``vega.plant``), added as they are.
    """
    table = Path(controller_table)
    meta = {
        META_SCENARIO: str(scenario_name),
        META_SCENARIO_YAML: str(scenario_yaml),
        META_SEED: str(int(seed)),
        META_CONTROLLER_TABLE: str(table.resolve()),
        META_CONTROLLER_TABLE_SHA256: file_sha256(table),
        META_GIT_REVISION: git_revision() if git_rev is None else str(git_rev),
        META_GUIDANCE_REFERENCE: "none",
    }
    if guidance_reference is not None:
        meta[META_GUIDANCE_REFERENCE] = str(Path(guidance_reference).resolve())
        meta[META_GUIDANCE_REFERENCE_SHA256] = file_sha256(guidance_reference)
    meta.update({str(k): str(v) for k, v in (extra or {}).items()})
    return meta


# ----------------------------------------------------------------------------- writer
class RunBagWriter:
    """Writer of one run bag (rosbag2 v9, MCAP) with the topics of :mod:`vega_bus.topics`.

    Parameters
    ----------
    path
        Bag directory to create (must not exist).
    metadata
        custom_data entries, string → string (ints and floats are converted); must hold
        every key of :data:`REQUIRED_METADATA`.

    Examples
    --------
    >>> with RunBagWriter(out, run_metadata(...)) as bag:        # doctest: +SKIP
    ...     bag.write("/vega/ins", stamp_ns, raw_cdr_bytes)

    Notes
    -----
    The bag is created by :meth:`open` (called by ``with``). :meth:`close` writes the MCAP
    summary and ``metadata.yaml``; leaving the ``with`` block closes it even when an exception
    is raised, so that the messages written so far stay readable.

    Crash safety (a writer killed before :meth:`close`): :meth:`open` writes the run metadata
    at once to ``RUN_METADATA_FILE`` beside the MCAP file, and the MCAP chunk in progress is
    closed and handed to the operating system every :data:`FLUSH_PERIOD_NS` of log time (the
    rosbags writer alone closes a chunk every 1 MiB, ≈ 40 s of a run). A killed writer so
    loses at most the last second of log time; :func:`vega_bags.repair.repair_bag` rebuilds
    the summary and ``metadata.yaml`` from what is on disk.
    """

    def __init__(self, path: str | Path, metadata: Mapping[str, Any]):
        self.path = Path(path)
        meta = {}
        for key, value in metadata.items():
            if not isinstance(key, str) or isinstance(value, bool) or \
                    not isinstance(value, (str, int, float)):
                raise ValueError(f"bag metadata {key!r}: keys and values must be strings, "
                                 f"got {type(value).__name__}")
            meta[key] = str(value)
        missing = [k for k in REQUIRED_METADATA if k not in meta]
        if missing:
            raise ValueError(f"bag metadata: missing {', '.join(missing)}")
        self.metadata = meta
        self._writer = None
        self._next_flush_ns = None
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    @property
    def is_open(self) -> bool:
        """True between :meth:`open` and :meth:`close`."""
        return self._writer is not None

    def open(self) -> "RunBagWriter":
        """Create the bag directory and add one connection per topic of the graph.

        Raises
        ------
        OSError
            If the path exists or cannot be created.
        """
        from rosbags.rosbag2 import StoragePlugin, WriterError

        if self._writer is not None:
            raise ValueError(f"bag {self.path}: already open")
        if self.path.exists():
            raise FileExistsError(f"bag {self.path}: exists already, not overwriting")
        store = vega_typestore()
        writer = _writer_class()(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        for key, value in self.metadata.items():
            writer.set_custom_data(key, value)
        try:
            writer.open()
        except WriterError as exc:
            raise OSError(f"bag {self.path}: {exc}") from None
        for topic in topics.ALL_TOPICS:
            self._connections[topic.name] = writer.add_connection(
                topic.name, topic.type_name, typestore=store,
                offered_qos_profiles=[topic_qos(topic)])
            self.counts[topic.name] = 0
        self._writer = writer
        run_metadata_path(self.path).write_text(json.dumps(
            {"format": "vega_run_metadata", "version": 1, "custom_data": self.metadata},
            indent=1, sort_keys=True) + "\n")
        self.flush()
        return self

    def flush(self) -> None:
        """Close the MCAP chunk in progress (schemas and channels go with the first) and hand
        the file's buffer to the operating system: what was written survives the process."""
        storage = self._writer.storage
        if storage.chunk.bio.tell():
            storage.close_chunk()
        storage.bio.flush()

    def write(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        """Append one message: its topic, log time (sim-time stamp) [ns], raw CDR bytes.

        Raises
        ------
        ValueError
            If the bag is not open or the topic is not one of the graph's.
        """
        if self._writer is None:
            raise ValueError(f"bag {self.path}: not open")
        try:
            connection = self._connections[topic]
        except KeyError:
            raise ValueError(f"bag {self.path}: topic {topic!r} is not a topic of the graph "
                             f"({', '.join(self._connections)})") from None
        t = int(log_time_ns)
        self._writer.write(connection, t, data)
        self.counts[topic] += 1
        if self._next_flush_ns is None:
            self._next_flush_ns = t + FLUSH_PERIOD_NS
        elif t >= self._next_flush_ns:
            self.flush()
            self._next_flush_ns = t + FLUSH_PERIOD_NS

    def close(self) -> None:
        """Write the MCAP summary and ``metadata.yaml``; idempotent.

        ``metadata.yaml`` says ``ros_distro: jazzy`` (the distribution whose rosbag2 format,
        version 9, and message definitions the bag holds; rosbags writes its own name there).
        ``starting_time`` is the first log time, i.e. simulation time since lift-off (0 for a
        run from lift-off), not wall-clock time."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()
            for mcap in self.path.glob("*.mcap"):
                write_section_crcs(mcap)
            meta = self.path / "metadata.yaml"
            text = meta.read_text()
            meta.write_text(text.replace("\n  ros_distro: rosbags\n",
                                         f"\n  ros_distro: {ROS_DISTRO}\n", 1))

    def __enter__(self) -> "RunBagWriter":
        return self.open()

    def __exit__(self, exc_type, exc, tb) -> bool:
        self.close()
        return False


# ----------------------------------------------------------------------------- reader
@dataclass(frozen=True)
class TopicColumns:
    """One topic of a bag as numpy columns, in bag (log-time) order.

    Attributes
    ----------
    topic, type_name
        Topic name and rosidl type.
    log_time_ns
        Log time of each message [ns] (int64).
    columns
        Field name → array (see the module docstring for the layout).
    counts
        Variable-size field name → per-message lengths (int64).
    """

    topic: str
    type_name: str
    log_time_ns: np.ndarray
    columns: Mapping[str, np.ndarray]
    counts: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.log_time_ns.size)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"topic {self.topic} has no column {name!r} "
                           f"(columns: {', '.join(self.columns)})") from None


@dataclass(frozen=True)
class RunBag:
    """A run bag loaded into memory: per-topic columns and the custom metadata.

    ``topics`` holds every vega topic present (:mod:`vega_bus.topics` names), possibly with
    zero messages; ``metadata`` the custom_data (empty if none); ``other_topics`` the names of
    topics that are not the graph's (ignored).
    """

    path: str
    topics: Mapping[str, TopicColumns]
    metadata: Mapping[str, str]
    other_topics: tuple[str, ...] = ()

    def __getitem__(self, topic: str) -> TopicColumns:
        try:
            return self.topics[topic]
        except KeyError:
            raise BagError(f"bag {self.path}: no topic {topic}") from None

    def has(self, topic: str) -> bool:
        """True if ``topic`` is in the bag."""
        return topic in self.topics


def _time_ns(t) -> int:
    return t.sec * NS_PER_S + t.nanosec


# CDR primitive → (numpy dtype, little endian; size [bytes])
_CDR_BASE = {"bool": ("?", 1), "byte": ("u1", 1), "char": ("u1", 1), "int8": ("i1", 1),
             "uint8": ("u1", 1), "int16": ("<i2", 2), "uint16": ("<u2", 2),
             "int32": ("<i4", 4), "uint32": ("<u4", 4), "int64": ("<i8", 8),
             "uint64": ("<u8", 8), "float32": ("<f4", 4), "float64": ("<f8", 8)}
_CDR_LE = b"\x00\x01"  # encapsulation: plain CDR, little endian
_TIME = "builtin_interfaces/msg/Time"


def _align(pos: int, size: int) -> int:
    return (pos + size - 1) // size * size


def _time_key(path: str, type_name: str) -> str:
    if path == "header.stamp" or (path == "clock" and type_name == topics.CLOCK.type_name):
        return "stamp_ns"
    return f"{path}_ns"


def _cdr_layout(store, root: str, type_name: str, data: bytes, pos: int, prefix: str,
                out: list) -> int:
    """Walk one CDR message from payload offset ``pos``; append its fields' places to ``out``.

    Entries: ``("time", key, offset)``, ``("base", name, offset, dtype, size)``,
    ``("array", name, offset, dtype, size, n)``, ``("seq", name, length_offset, offset,
    dtype, size, n)``, ``("string", length_offset, length, name)``. Returns the end offset.
    """
    from rosbags.typesys.store import Nodetype

    for name, (kind, detail) in store.fielddefs[type_name][1]:
        path = f"{prefix}{name}"
        if kind == Nodetype.NAME:
            if detail == _TIME:
                pos = _align(pos, 4)
                out.append(("time", _time_key(path, root), pos))
                pos += 8
            else:
                pos = _cdr_layout(store, root, detail, data, pos, f"{path}.", out)
            continue
        if kind == Nodetype.BASE:
            if detail[0] == "string":
                pos = _align(pos, 4)
                length = int.from_bytes(data[4 + pos:8 + pos], "little")
                out.append(("string", pos, length, path))
                pos += 4 + length
                continue
            dtype, size = _CDR_BASE[detail[0]]
            pos = _align(pos, size)
            out.append(("base", path, pos, dtype, size))
            pos += size
            continue
        (sub_kind, sub_detail), n = detail
        if sub_kind != Nodetype.BASE or sub_detail[0] not in _CDR_BASE:
            raise _NotFlat(path)
        dtype, size = _CDR_BASE[sub_detail[0]]
        if kind == Nodetype.ARRAY:
            pos = _align(pos, size)
            out.append(("array", path, pos, dtype, size, n))
            pos += size * n
        else:
            pos = _align(pos, 4)
            n = int.from_bytes(data[4 + pos:8 + pos], "little")
            start = _align(pos + 4, size) if n else pos + 4
            out.append(("seq", path, pos, start, dtype, size, n))
            pos = start + size * n
    return pos


def cdr_offsets(type_name: str, data) -> dict[str, int]:
    """Where the fields of one raw CDR message sit, from the computed layout.

    Parameters
    ----------
    type_name
        Its rosidl type (a type of :func:`vega_typestore`).
    data
        The raw message (encapsulation header included), little-endian CDR.

    Returns
    -------
    dict
        Byte offset in ``data`` of each field: ``builtin_interfaces/Time`` fields by column
        key (``stamp_ns``, ``sample_stamp_ns``: the offset of ``sec``, ``nanosec`` follows),
        scalars and fixed arrays by name (``seq``, ``pitch_rad``, ``bending_q``), strings and
        sequences by name at their uint32 length (``header.frame_id``). Strings and sequences
        shift what follows them, so the offsets hold for messages with the same lengths.
    """
    layout: list = []
    _cdr_layout(vega_typestore(), type_name, type_name, data, 0, "", layout)
    return {entry[3] if entry[0] == "string" else entry[1]:
            4 + (entry[1] if entry[0] == "string" else entry[2]) for entry in layout}


class _NotFlat(Exception):
    """The fast decoder does not apply (nested sequences, differing layouts, …)."""


def _as_column(raw: np.ndarray, dtype: str) -> np.ndarray:
    kind = np.dtype(dtype).kind
    if kind == "f":
        return raw.astype(np.float64, copy=False)
    if kind == "b":
        return raw.astype(bool, copy=False)
    return raw.astype(np.int64)


def _fast_columns(store, type_name: str, raw: list) -> tuple[dict, dict]:
    """Columns of same-layout CDR messages, read straight from the bytes with numpy.

    Applies when every message has the layout of the first (same length, same string and
    sequence lengths, little-endian CDR); raises :class:`_NotFlat` otherwise.
    """
    layout: list = []
    length = len(raw[0])
    if raw[0][:2] != _CDR_LE:
        raise _NotFlat("byte order")
    if 4 + _cdr_layout(store, type_name, type_name, raw[0], 0, "", layout) > length:
        raise _NotFlat("truncated")
    if any(len(d) != length for d in raw):
        raise _NotFlat("lengths differ")
    n = len(raw)
    mat = np.frombuffer(b"".join(raw), dtype=np.uint8).reshape(n, length)

    def field(offset: int, dtype: str, size: int, count: int = 1) -> np.ndarray:
        lo = 4 + offset
        return np.ascontiguousarray(mat[:, lo:lo + size * count]).view(dtype)

    def same(offset: int, value: int) -> None:
        if not np.all(field(offset, "<u4", 4) == value):
            raise _NotFlat("variable lengths differ")

    if not np.all(mat[:, :2] == np.frombuffer(_CDR_LE, np.uint8)):
        raise _NotFlat("byte order")
    cols: dict[str, np.ndarray] = {}
    counts: dict[str, np.ndarray] = {}
    for entry in layout:
        kind = entry[0]
        if kind == "time":
            _, key, off = entry
            cols[key] = (field(off, "<i4", 4)[:, 0].astype(np.int64) * NS_PER_S
                         + field(off + 4, "<u4", 4)[:, 0])
        elif kind == "base":
            _, name, off, dtype, size = entry
            cols[name] = _as_column(field(off, dtype, size)[:, 0], dtype)
        elif kind == "array":
            _, name, off, dtype, size, k = entry
            cols[name] = _as_column(field(off, dtype, size, k), dtype)
        elif kind == "seq":
            _, name, len_off, off, dtype, size, k = entry
            same(len_off, k)
            cols[name] = _as_column(field(off, dtype, size, k).reshape(-1), dtype)
            counts[name] = np.full(n, k, dtype=np.int64)
        else:
            same(entry[1], entry[2])
    return cols, counts


def _decode_topic(store, path: Path, name: str, type_name: str,
                  raw: list) -> tuple[dict, dict]:
    """Columns of one topic: the fast numpy reader, else rosbags' deserialiser."""
    if raw:
        try:
            return _fast_columns(store, type_name, raw)
        except (_NotFlat, ValueError, IndexError):
            pass
    try:
        messages = [store.deserialize_cdr(data, type_name) for data in raw]
    except Exception as exc:  # noqa: BLE001 - rosbags' decoder raises many types on bad bytes
        raise BagError(f"bag {path}: topic {name}: undecodable {type_name} message "
                       f"({one_line(exc)})") from None
    return _columns_of(store, type_name, messages)


def _columns_of(store, type_name: str, messages: list) -> tuple[dict, dict]:
    """Columns of the decoded ``messages`` of type ``type_name``."""
    from rosbags.typesys.store import Nodetype

    cols: dict[str, np.ndarray] = {}
    counts: dict[str, np.ndarray] = {}
    n = len(messages)
    for name, (kind, detail) in store.fielddefs[type_name][1]:
        values = [getattr(m, name) for m in messages]
        if kind == Nodetype.NAME and detail == "std_msgs/msg/Header":
            cols["stamp_ns"] = np.fromiter((_time_ns(v.stamp) for v in values), np.int64, n)
        elif kind == Nodetype.NAME and detail == "builtin_interfaces/msg/Time":
            key = "stamp_ns" if type_name == topics.CLOCK.type_name else f"{name}_ns"
            cols[key] = np.fromiter((_time_ns(v) for v in values), np.int64, n)
        elif kind == Nodetype.BASE:
            base = detail[0]
            if base == "string":
                continue
            dtype = bool if base == "bool" else (np.float64 if base.startswith("float")
                                                 else np.int64)
            cols[name] = np.array(values, dtype=dtype)
        elif kind == Nodetype.ARRAY:
            cols[name] = (np.array(values, dtype=float).reshape(n, detail[1])
                          if n else np.zeros((0, detail[1])))
        elif kind == Nodetype.SEQUENCE:
            counts[name] = np.fromiter((len(v) for v in values), np.int64, n)
            cols[name] = (np.concatenate(values).astype(float, copy=False) if n
                          else np.zeros(0))
    return cols, counts


def _open_reader(path: Path):
    """An opened rosbags reader of the bag directory ``path`` (BagError otherwise)."""
    from rosbags.rosbag2 import Reader

    if not path.exists():
        raise BagError(f"bag {path}: no such file or directory")
    if not path.is_dir():
        raise BagError(f"bag {path}: not a rosbag2 directory (expected a directory with "
                       f"metadata.yaml)")
    if not (path / "metadata.yaml").is_file():
        if any(path.glob("*.mcap")):
            raise BagError(f"bag {path}: no metadata.yaml next to its MCAP file: the bag was "
                           f"not closed (its recorder was killed?); `vega bag repair {path}` "
                           f"recovers what was written")
        raise BagError(f"bag {path}: not a rosbag2 directory (no metadata.yaml)")
    check_section_crcs(path)
    reader = Reader(path)
    try:
        reader.open()
    except Exception as exc:  # noqa: BLE001 - rosbags raises ReaderError, KeyError, struct/ValueError, …
        raise BagError(f"bag {path}: unreadable ({one_line(exc)})") from None
    return reader


def _vega_connections(path: Path, reader) -> tuple[dict, tuple[str, ...]]:
    """The graph topics' connections (topic → connection) and the other topic names."""
    known = {t.name: t for t in topics.ALL_TOPICS}
    wanted, other = {}, []
    for conn in reader.connections:
        topic = known.get(conn.topic)
        if topic is None:
            other.append(conn.topic)
            continue
        if conn.msgtype != topic.type_name:
            raise BagError(f"bag {path}: foreign bag: topic {conn.topic} has type "
                           f"{conn.msgtype}, expected {topic.type_name}")
        wanted[conn.topic] = conn
    if not any(t.name in wanted for t in topics.DATA_TOPICS):
        found = ", ".join(sorted(other)) or "no topics"
        raise BagError(f"bag {path}: foreign bag: none of the vega topics "
                       f"({', '.join(t.name for t in topics.DATA_TOPICS)}); it holds {found}")
    return wanted, tuple(sorted(set(other)))


@contextmanager
def _run_bag_reader(path: Path):
    """(opened reader, graph-topic connections, other topic names); closes the reader."""
    reader = _open_reader(path)
    try:
        wanted, other = _vega_connections(path, reader)
        yield reader, wanted, other
    finally:
        with suppress(Exception):
            reader.close()


def _messages(path: Path, reader, connections) -> Iterator[tuple[Any, int, bytes]]:
    """The reader's messages of ``connections``; storage errors as BagError."""
    try:
        yield from reader.messages(connections=connections)
    except Exception as exc:  # noqa: BLE001 - truncated chunks, bad records, decompression errors, …
        raise BagError(f"bag {path}: corrupt data ({one_line(exc)})") from None


def iter_raw_messages(path: str | Path, topic_names=None) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time [ns], raw CDR bytes) of a run bag's graph topics, in log-time order.

    Parameters
    ----------
    path
        Bag directory.
    topic_names
        Topics to yield (default: every graph topic in the bag).

    Raises
    ------
    BagError
        Missing, corrupt or foreign bag (also while iterating, if the data is truncated).
    """
    path = Path(path)
    with _run_bag_reader(path) as (reader, wanted, _):
        conns = [c for name, c in wanted.items() if topic_names is None or name in topic_names]
        if conns:
            for conn, log_time, data in _messages(path, reader, conns):
                yield conn.topic, log_time, data


def read_run_bag(path: str | Path) -> RunBag:
    """Load a run bag: every graph topic as numpy columns, and the custom metadata.

    Raises
    ------
    BagError
        One line: missing path, not a rosbag2 directory, unreadable or truncated storage,
        undecodable message, a message count in metadata.yaml that is not the file's, or a
        foreign bag (no vega topic, or a vega topic with another message type).
    """
    path = Path(path)
    store = vega_typestore()
    with _run_bag_reader(path) as (reader, wanted, other):
        custom = dict(getattr(reader.storage.metadata, "custom", None) or {})
        raw: dict[str, list] = {name: [] for name in wanted}
        times: dict[str, list] = {name: [] for name in wanted}
        for conn, log_time, data in _messages(path, reader, list(wanted.values())):
            raw[conn.topic].append(data)
            times[conn.topic].append(log_time)
    for name, conn in wanted.items():
        # metadata.yaml is outside the MCAP CRCs: its counts must be the file's (what
        # `ros2 bag info` and other rosbag2 tools show)
        if conn.msgcount != len(raw[name]):
            raise BagError(f"bag {path}: metadata.yaml lists {conn.msgcount} messages on "
                           f"{name}, the MCAP file holds {len(raw[name])}")
    loaded = {}
    for name, conn in wanted.items():
        cols, counts = _decode_topic(store, path, name, conn.msgtype, raw[name])
        loaded[name] = TopicColumns(name, conn.msgtype, np.array(times[name], dtype=np.int64),
                                    cols, counts)
    return RunBag(str(path), loaded, {str(k): str(v) for k, v in custom.items()}, other)
