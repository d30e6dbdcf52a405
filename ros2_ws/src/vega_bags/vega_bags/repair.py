"""`vega bag repair BAG`: make a run bag whose writer was killed readable again (the analogue
of ``ros2 bag reindex``).

A recorder killed before it closed its bag leaves an MCAP file without summary and footer and
no ``metadata.yaml``; the run metadata is on disk from the start
(:data:`vega_bags.bagio.RUN_METADATA_FILE`) and the chunks up to the last flush (at most one
second of log time before the kill, :class:`vega_bags.bagio.RunBagWriter`). The repair scans
the file record by record (MCAP: 8-byte magic, then records ``opcode u8, length u64, body``),
stops at the first record that is cut off, keeps every message of every complete chunk (and of
any message record outside a chunk), checks that the channels are the run graph's topics with
their types, and writes a complete bag with the same messages, log times and run metadata
through :class:`vega_bags.bagio.RunBagWriter`. The cut file is kept beside it as
``<name>.mcap.truncated``; nothing is deleted.
"""

from __future__ import annotations

import json
import shutil
import struct
import tempfile
import zlib
from dataclasses import dataclass
from pathlib import Path

from vega_core.errors import one_line

from vega_bus import topics

from vega_bags import bagio

__all__ = ["RepairReport", "scan_mcap", "repair_bag"]

_MAGIC = b"\x89MCAP0\r\n"
_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 0x03, 0x04, 0x05, 0x06
_OP_FOOTER = 0x02


@dataclass(frozen=True)
class RepairReport:
    """What a repair found and wrote."""

    bag: Path
    messages: dict[str, int]
    last_log_time_ns: int | None
    kept: Path
    bytes_dropped: int

    def text(self) -> str:
        """One line for the console."""
        counts = ", ".join(f"{k} {v}" for k, v in self.messages.items())
        end = "-" if self.last_log_time_ns is None else f"{self.last_log_time_ns / 1e9:.3f} s"
        return (f"repaired {self.bag}: {sum(self.messages.values())} messages recovered "
                f"({counts}), up to log time {end}; {self.bytes_dropped} bytes at the end were "
                f"an incomplete record; the cut file is kept as {self.kept.name}")


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return bytes(buf[pos + 4:pos + 4 + n]).decode(), pos + 4 + n


def _records(buf: memoryview, start: int, end: int):
    """(opcode, body) of every complete record in buf[start:end]; the offset where they stop."""
    pos = start
    while pos + 9 <= end:
        op = buf[pos]
        (length,) = struct.unpack_from("<Q", buf, pos + 1)
        if pos + 9 + length > end:
            break
        yield op, buf[pos + 9:pos + 9 + length]
        pos += 9 + length
    return pos


def scan_mcap(data: bytes) -> tuple[dict[int, str], list[tuple[int, int, bytes]], int]:
    """Channels (id → topic), messages (channel id, log time, data) in file order, and the
    number of bytes after the last complete record.

    Raises
    ------
    ValueError
        Not an MCAP file (bad magic), or a compressed chunk (the product writes none).
    """
    buf = memoryview(data)
    if bytes(buf[:8]) != _MAGIC:
        raise ValueError("not an MCAP file (bad magic)")
    channels: dict[int, str] = {}
    messages: list[tuple[int, int, bytes]] = []
    bad_chunks = 0

    def take(op, body):
        if op == _OP_CHANNEL:
            (cid,) = struct.unpack_from("<H", body, 0)
            topic, _ = _string(body, 4)
            channels[cid] = topic
        elif op == _OP_MESSAGE:
            cid, _seq, log_time = struct.unpack_from("<HIQ", body, 0)
            messages.append((cid, log_time, bytes(body[22:])))

    pos, end = 8, len(buf)
    records = _records(buf, pos, end)
    while True:
        try:
            op, body = next(records)
        except StopIteration as stop:
            pos = stop.value
            break
        if op == _OP_FOOTER:
            pos = end
            break
        if op == _OP_CHUNK:
            compression, at = _string(body, 28)
            if compression:
                raise ValueError(f"compressed chunk ({compression!r}) not supported")
            (size,) = struct.unpack_from("<Q", body, at)
            inner = body[at + 8:at + 8 + size]
            (crc,) = struct.unpack_from("<I", body, 24)
            if crc and zlib.crc32(inner) != crc:
                bad_chunks += 1             # a damaged chunk: its messages are not trusted
                continue
            inner_records = _records(inner, 0, len(inner))
            for inner_op, inner_body in inner_records:
                take(inner_op, inner_body)
        else:
            take(op, body)
    if bad_chunks:
        raise ValueError(f"{bad_chunks} chunk(s) fail their CRC-32 (the file is damaged, not "
                         f"only cut)")
    return channels, messages, end - pos


def repair_bag(path: str | Path) -> RepairReport:
    """Rebuild a complete run bag from the MCAP file a killed writer left in ``path``.

    Raises
    ------
    BagError
        One line: not a bag directory, a complete bag (nothing to repair), no run metadata on
        disk, not an MCAP file, or channels that are not the run graph's.
    """
    bag = Path(path)
    if not bag.is_dir():
        raise bagio.BagError(f"bag {bag}: not a bag directory")
    mcaps = sorted(bag.glob("*.mcap"))
    if len(mcaps) != 1:
        raise bagio.BagError(f"bag {bag}: expected one .mcap file, found {len(mcaps)}")
    mcap = mcaps[0]
    if (bag / "metadata.yaml").is_file():
        raise bagio.BagError(f"bag {bag}: has its metadata.yaml: a closed bag, nothing to repair")
    meta_path = bagio.run_metadata_path(bag)
    try:
        custom = json.loads(meta_path.read_text())["custom_data"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise bagio.BagError(f"bag {bag}: no usable run metadata ({meta_path.name}: "
                             f"{one_line(exc)}); cannot repair") from None
    try:
        channels, messages, dropped = scan_mcap(mcap.read_bytes())
    except ValueError as exc:
        raise bagio.BagError(f"bag {bag}: {mcap.name}: {exc}") from None
    known = {t.name for t in topics.ALL_TOPICS}
    foreign = sorted(set(channels.values()) - known)
    if foreign:
        raise bagio.BagError(f"bag {bag}: foreign topics {', '.join(foreign)}; not a run bag")
    missing = sorted({cid for cid, _, _ in messages} - set(channels))
    if missing:
        raise bagio.BagError(f"bag {bag}: messages on undeclared channels {missing}")
    with tempfile.TemporaryDirectory(prefix="vega-repair-", dir=bag.parent) as tmp:
        new = Path(tmp) / bag.name
        with bagio.RunBagWriter(new, custom) as writer:
            for cid, t_ns, data in messages:
                writer.write(channels[cid], t_ns, data)
            counts = dict(writer.counts)
        kept = mcap.with_name(mcap.name + ".truncated")
        mcap.rename(kept)
        for item in new.iterdir():
            if item.name != bagio.RUN_METADATA_FILE:
                shutil.move(str(item), bag / item.name)
    last = max((t for _, t, _ in messages), default=None)
    return RepairReport(bag=bag, messages=counts, last_log_time_ns=last, kept=kept,
                        bytes_dropped=dropped)
