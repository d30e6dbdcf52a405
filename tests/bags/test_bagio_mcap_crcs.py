"""The MCAP section CRCs of run bags: written by the writer, checked by the reader.

MCAP specification: the DataEnd record's CRC-32 covers the file from its first byte to the
DataEnd record, the Footer's summary CRC covers the summary section through the Footer's
summary_offset_start field, each chunk's CRC its uncompressed records; 0 means "not computed".
Independent references: the records read by hand with :mod:`struct` (opcode u8, length u64,
body) and the CRCs computed with :mod:`zlib`, never through the code under test; Foxglove's
``mcap`` reader validating every CRC; minimal MCAP files built by hand. A flipped byte in the
data section or in the summary is refused in one line naming both CRCs.
"""

import struct

import pytest

from bagio_bytes import INS_OFFSETS, MAGIC, _raw, _small_bag
from vega_bags import bagio
from vega_bus import topics


def _footer_fields(data):
    """(summary_start, summary_offset_start, summary_crc, footer offset) read by hand: the
    footer record (opcode 0x02, length 20) sits right before the closing magic."""
    at = len(data) - 8 - 29
    op, length, start, offset_start, crc = struct.unpack_from("<BQQQI", data, at)
    assert data[-8:] == MAGIC and op == 0x02 and length == 20
    return start, offset_start, crc, at


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
