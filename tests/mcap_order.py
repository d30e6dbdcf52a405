"""The messages of a run bag's MCAP file in file order (a reader of its own, by the MCAP
specification: records opcode u8 + length u64 + body; Channel 0x04, Message 0x05, Chunk 0x06
with its records inside, uncompressed as our writer leaves them). rosbags' reader yields
messages sorted by log time, which hides the order in the file; this one does not."""

import struct
from pathlib import Path

__all__ = ["file_messages"]


def _string(buf, pos):
    (n,) = struct.unpack_from("<I", buf, pos)
    return bytes(buf[pos + 4:pos + 4 + n]).decode(), pos + 4 + n


def _records(buf, pos, end):
    while pos + 9 <= end:
        op, length = buf[pos], struct.unpack_from("<Q", buf, pos + 1)[0]
        yield op, buf[pos + 9:pos + 9 + length]
        pos += 9 + length


def file_messages(bag_dir):
    """[(topic, log time [ns], payload bytes)] of the bag's one MCAP file, in file order."""
    (path,) = sorted(Path(bag_dir).glob("*.mcap"))
    buf = memoryview(path.read_bytes())
    topics, out = {}, []

    def take(op, body):
        if op == 0x04:
            (channel_id,) = struct.unpack_from("<H", body, 0)
            topics[channel_id] = _string(body, 4)[0]
        elif op == 0x05:
            channel_id, _, log_time = struct.unpack_from("<HIQ", body, 0)
            out.append((topics[channel_id], log_time, bytes(body[22:])))

    for op, body in _records(buf, 8, len(buf) - 8):
        if op == 0x06:
            compression, at = _string(body, 28)
            assert compression == "", compression
            (size,) = struct.unpack_from("<Q", body, at)
            for inner_op, inner in _records(body[at + 8:at + 8 + size], 0, size):
                take(inner_op, inner)
        else:
            take(op, body)
    return out
