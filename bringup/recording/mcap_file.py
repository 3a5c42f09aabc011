"""MCAP files at the record level: what a cut or damaged file still holds, CRCs, crash-safe chunks.

A bag's ``.mcap`` is the truth about what was recorded (https://mcap.dev/spec): its channels,
messages and times. A complete file ends with a summary (schemas, channels, chunk indexes,
statistics) and a footer; rosbags reads those. A file whose writer was killed has no summary and no
footer, and rosbags, ``mcap`` and Foxglove's indexed readers refuse it. :func:`scan_mcap` walks such a
file from its header, one record at a time (opcode, uint64 length, body), and keeps every record
that is whole:

* a Chunk (0x06) counts when its record is complete, it decompresses to its stated size and, when
  a CRC was written, the CRC matches; its Schema (0x03), Channel (0x04) and Message (0x05) records
  are read (rosbags writes schemas and channels inside the chunks);
* a chunk whose record is whole but whose content is damaged is skipped and named (the records
  after it are still read: the framing tells where the next one starts);
* the scan stops at DataEnd (0x0F: the data section is complete) or at the first record that runs
  past the end of the file (the writer was stopped while writing it, or the file was cut): what
  follows is lost and its size is given.

Metadata records (0x0C) in the data section are read too: bringup/recording/bag.py writes one named
``constellation`` right after the header (the bag's epoch and custom data), so a bag cut before its
summary still knows its clock.

:func:`iter_messages` gives the messages of the good chunks (and unchunked ones) in log-time order,
decompressing one chunk at a time as the merge needs it.

Writing (used by bag.py's BagWriter on rosbags' McapWriter): :func:`with_chunk_crc` makes a
writer's chunk close write the chunk's ``uncompressed_crc`` and flush the file, so every closed chunk
is in the file (in the kernel's page cache: a killed process loses only its open chunk);
:func:`write_file_crcs` writes DataEnd's ``data_section_crc`` and the Footer's ``summary_crc`` when the
file is complete.

How we know it is right: tests/unit/test_bag_recovery.py cuts a bag written by BagWriter at every
chunk boundary and at random offsets, and checks that the scan returns exactly the messages of the
chunks before the cut (compared with the full file read by rosbags), names the lost bytes, skips a
chunk with a flipped byte, and reads a file missing only its last 8 bytes completely.
"""

from __future__ import annotations

import heapq
import struct
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import MethodType

from rosbags.rosbag2.storage_mcap import DECOMPRESSORS, McapWriter

__all__ = ["MAGIC", "ChunkRef", "McapScan", "McapScanError", "iter_messages", "metadata_record",
           "read_leading_metadata", "scan_mcap", "with_chunk_crc", "write_file_crcs"]

MAGIC = b"\x89MCAP0\r\n"
_OP_LEN = struct.Struct("<BQ")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<QQQI")  # start time, end time, uncompressed size, uncompressed crc
_MSG_HEAD = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time
_MAX_RECORD = 1 << 34  # 16 GiB: a longer record length is damage, not data


class McapScanError(ValueError):
    """The file is not an MCAP file at all (no magic, no header); the message says why."""


@dataclass(frozen=True)
class ChunkRef:
    """Where a good chunk's compressed records are in the file."""

    offset: int  # of the compressed records
    compressed_size: int
    uncompressed_size: int
    crc: int
    compression: str
    start_time: int
    end_time: int


@dataclass
class McapScan:
    """What :func:`scan_mcap` found (times are the file's log times, Unix ns for our bags)."""

    path: Path
    file_bytes: int
    good_bytes: int = 0  # the file up to the end of the last whole record read
    data_end: bool = False  # the DataEnd record was reached: the data section is whole
    footer: bool = False  # the file ends with a footer and the closing magic
    chunks: list[ChunkRef] = field(default_factory=list)
    bad_chunks: list[str] = field(default_factory=list)  # "chunk at byte N: why"
    schemas: dict[int, str] = field(default_factory=dict)  # id -> message type
    channels: dict[int, tuple[str, int, str]] = field(default_factory=dict)  # id -> (topic, schema id, encoding)
    counts: dict[int, int] = field(default_factory=dict)  # channel id -> messages
    start_time: int | None = None
    end_time: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    loose: list[tuple[int, int, bytes]] = field(default_factory=list)  # unchunked (log time, channel, data)
    stop_reason: str = ""  # why the scan stopped before DataEnd ("" if it reached it)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    @property
    def lost_bytes(self) -> int:
        """Bytes of the file after the last whole record, before DataEnd (a cut record's part)."""
        return 0 if self.data_end else self.file_bytes - self.good_bytes

    def msgtype(self, channel_id: int) -> str:
        _topic, schema_id, _enc = self.channels[channel_id]
        return self.schemas.get(schema_id, "")


def _string(buf, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise ValueError("string runs past its record")
    return bytes(buf[pos + 4:end]).decode("utf-8"), end


def _string_map(buf, pos: int) -> tuple[dict[str, str], int]:
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise ValueError("map runs past its record")
    out = {}
    p = pos + 4
    while p < end:
        k, p = _string(buf, p)
        v, p = _string(buf, p)
        out[k] = v
    return out, end


def metadata_record(name: str, data: dict[str, str]) -> bytes:
    """The bytes of an MCAP Metadata record (opcode 0x0C): name, then a string map."""
    def s(x: str) -> bytes:
        b = x.encode("utf-8")
        return _U32.pack(len(b)) + b

    body_map = b"".join(s(k) + s(v) for k, v in data.items())
    body = s(name) + _U32.pack(len(body_map)) + body_map
    return _OP_LEN.pack(0x0C, len(body)) + body


def read_leading_metadata(path: Path, name: str) -> dict[str, str] | None:
    """The Metadata record ``name`` if it directly follows the file's Header record, else None (a
    cheap read of the first few KiB: where bag.py writes its ``constellation`` record)."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    try:
        if head[:8] != MAGIC:
            return None
        op, n = _OP_LEN.unpack_from(head, 8)
        pos = 8 + 9 + n
        if op != 0x01:
            return None
        op, n = _OP_LEN.unpack_from(head, pos)
        if op != 0x0C or pos + 9 + n > len(head):
            return None
        rec = memoryview(head)[pos + 9:pos + 9 + n]
        got, p = _string(rec, 0)
        if got != name:
            return None
        data, _ = _string_map(rec, p)
        return data
    except (struct.error, ValueError, UnicodeDecodeError):
        return None


def _inner_records(scan: McapScan, raw, *, count: bool, where: str) -> Iterator[tuple[int, int, memoryview]]:
    """Walk the records of a decompressed chunk: schemas and channels go into ``scan``; messages
    are counted (``count``) and yielded as (log time, channel, data)."""
    n = len(raw)
    pos = 0
    mv = memoryview(raw)
    while pos < n:
        if pos + 9 > n:
            raise ValueError(f"{where}: a record header runs past the chunk's end")
        op, length = _OP_LEN.unpack_from(raw, pos)
        body, end = pos + 9, pos + 9 + length
        if end > n:
            raise ValueError(f"{where}: a record runs past the chunk's end")
        if op == 0x05:
            if length < 22:
                raise ValueError(f"{where}: message record too short")
            cid, _seq, log_time, _pub = _MSG_HEAD.unpack_from(raw, body)
            if count:
                scan.counts[cid] = scan.counts.get(cid, 0) + 1
                if scan.start_time is None or log_time < scan.start_time:
                    scan.start_time = log_time
                if scan.end_time is None or log_time > scan.end_time:
                    scan.end_time = log_time
            yield log_time, cid, mv[body + 22:end]
        elif op == 0x03 and count:
            (sid,) = _U16.unpack_from(raw, body)
            name, _ = _string(mv[:end], body + 2)
            scan.schemas[sid] = name
        elif op == 0x04 and count:
            cid, sid = struct.unpack_from("<HH", raw, body)
            topic, p = _string(mv[:end], body + 4)
            enc, _ = _string(mv[:end], p)
            scan.channels[cid] = (topic, sid, enc)
        pos = end


def _decompress(ref: ChunkRef, data: bytes) -> bytes:
    if ref.compression not in DECOMPRESSORS:
        raise ValueError(f"unsupported compression {ref.compression!r}")
    raw = DECOMPRESSORS[ref.compression](data, ref.uncompressed_size)
    if len(raw) != ref.uncompressed_size:
        raise ValueError(f"decompressed to {len(raw)} bytes, expected {ref.uncompressed_size}")
    if ref.crc and zlib.crc32(raw) != ref.crc:
        raise ValueError("CRC mismatch")
    return raw


def scan_mcap(path: str | Path) -> McapScan:
    """Scan an MCAP file from its start (module docstring). Raises :class:`McapScanError` only when
    the file is no MCAP file at all; any damage after the header is described in the result."""
    path = Path(path)
    with open(path, "rb") as fh:
        size = fh.seek(0, 2)
        fh.seek(0)
        scan = McapScan(path=path, file_bytes=size)
        if fh.read(8) != MAGIC:
            raise McapScanError("not an MCAP file (no MCAP magic at its start)")
        head = fh.read(9)
        if len(head) < 9:
            raise McapScanError("the file ends inside its header record")
        op, length = _OP_LEN.unpack(head)
        if op != 0x01 or length > _MAX_RECORD:
            raise McapScanError("no MCAP header record after the magic")
        pos = fh.seek(17 + length)
        if pos > size:
            raise McapScanError("the file ends inside its header record")
        scan.good_bytes = pos
        while True:
            head = fh.read(9)
            if len(head) == 0:
                scan.stop_reason = f"the file ends at byte {pos} with no DataEnd record"
                break
            if len(head) < 9:
                scan.stop_reason = f"the file ends inside a record header at byte {pos}"
                break
            op, length = _OP_LEN.unpack(head)
            if length > _MAX_RECORD or pos + 9 + length > size:
                scan.stop_reason = (f"a record (opcode 0x{op:02x}) at byte {pos} runs past the file's end "
                                    f"({pos + 9 + length} > {size} bytes)")
                break
            if op == 0x0F:  # DataEnd: the data section is whole
                scan.data_end = True
                scan.good_bytes = pos + 9 + length
                break
            if op == 0x06:
                _read_chunk(scan, fh, pos, length)
            elif op in (0x03, 0x04, 0x05, 0x0C):
                body = fh.read(length)
                try:
                    if op == 0x0C:
                        name, p = _string(body, 0)
                        scan.metadata[name], _ = _string_map(body, p)
                    else:
                        rec = _OP_LEN.pack(op, length) + body
                        for t, cid, data in _inner_records(scan, rec, count=True, where=f"record at byte {pos}"):
                            scan.loose.append((t, cid, bytes(data)))
                except (struct.error, ValueError, UnicodeDecodeError) as exc:
                    scan.bad_chunks.append(f"record at byte {pos}: {exc}")
            pos = fh.seek(pos + 9 + length)
            scan.good_bytes = pos
        if scan.data_end:
            fh.seek(size - 8)
            scan.footer = size >= 8 + 29 and fh.read(8) == MAGIC
    scan.loose.sort(key=lambda m: m[0])
    return scan


def _read_chunk(scan: McapScan, fh, pos: int, length: int) -> None:
    body = fh.read(length)
    try:
        start, end, usize, crc = _CHUNK_HEAD.unpack_from(body, 0)
        comp, p = _string(body, 28)
        (csize,) = _U64.unpack_from(body, p)
        if p + 8 + csize > len(body):
            raise ValueError("compressed records run past the chunk record")
        ref = ChunkRef(pos + 9 + p + 8, csize, usize, crc, comp, start, end)
        raw = _decompress(ref, body[p + 8:p + 8 + csize])
        for _ in _inner_records(scan, raw, count=True, where=f"chunk at byte {pos}"):
            pass
    except (struct.error, ValueError, UnicodeDecodeError, RuntimeError) as exc:
        scan.bad_chunks.append(f"chunk at byte {pos}: {exc}")
        return
    except Exception as exc:  # noqa: BLE001 - the decompressors raise their own error types
        scan.bad_chunks.append(f"chunk at byte {pos}: {type(exc).__name__}: {exc}")
        return
    scan.chunks.append(ref)


def iter_messages(scan: McapScan, channel_ids: Iterable[int] | None = None) -> Iterator[tuple[int, int, bytes]]:
    """(log time, channel id, data) of every message the scan kept, in log-time order (ties in
    file order), one chunk decompressed at a time."""
    want = None if channel_ids is None else set(channel_ids)

    def one(ref: ChunkRef, k: int):
        # first a key that sorts the chunk by its start time, so the merge opens it only when due
        yield (ref.start_time, k, -1, None)
        with open(scan.path, "rb") as fh:
            fh.seek(ref.offset)
            raw = _decompress(ref, fh.read(ref.compressed_size))
        msgs = [(t, k, i, (cid, bytes(data)))
                for i, (t, cid, data) in enumerate(_inner_records(scan, raw, count=False, where=""))
                if want is None or cid in want]
        msgs.sort()
        yield from msgs

    streams = [one(ref, k) for k, ref in enumerate(scan.chunks)]
    loose = [(t, len(scan.chunks), i, (cid, data)) for i, (t, cid, data) in enumerate(scan.loose)
             if want is None or cid in want]
    streams.append(iter(loose))
    for t, _k, _i, item in heapq.merge(*streams):
        if item is not None:
            yield t, item[0], item[1]


# -- writing ------------------------------------------------------------------------------------------
_CRC_AT = 1 + 8 + 8 + 8 + 8  # Chunk record: opcode, length, start time, end time, uncompressed size


def with_chunk_crc(storage: McapWriter) -> None:
    """Make this McapWriter's chunk close (rosbags' own or the fast one) write the chunk's
    ``uncompressed_crc`` (CRC-32 of the uncompressed records) in place of rosbags' 0, then flush the
    file: a closed chunk is never left in the process's buffer."""
    close = storage.close_chunk

    def close_chunk(self: McapWriter) -> None:
        crc = zlib.crc32(self.chunk.bio.getbuffer())
        start = self.bio.tell()
        close()
        end = self.bio.tell()
        self.bio.seek(start + _CRC_AT)
        self.bio.write(_U32.pack(crc))
        self.bio.seek(end)
        self.bio.flush()

    storage.close_chunk = MethodType(close_chunk, storage)


_FOOTER = struct.Struct("<BQQQI")  # opcode 0x02, length 20, summary_start, summary_offset_start, summary_crc


def write_file_crcs(path: Path) -> None:
    """Write DataEnd's ``data_section_crc`` (CRC-32 of every byte before the DataEnd record) and the
    Footer's ``summary_crc`` (the summary section and the Footer up to its summary_offset_start)
    into a complete MCAP file."""
    with open(path, "r+b") as fh:
        size = fh.seek(0, 2)
        foot = size - 8 - _FOOTER.size
        fh.seek(foot)
        op, length, summary_start, _offsets, _crc = _FOOTER.unpack(fh.read(_FOOTER.size))
        if op != 0x02 or length != 20 or summary_start == 0:
            raise ValueError(f"{path}: no MCAP footer with a summary where expected")
        data_end = summary_start - 13  # DataEnd: opcode 0x0F, length 4, crc
        fh.seek(data_end)
        if fh.read(9) != b"\x0f" + struct.pack("<Q", 4):
            raise ValueError(f"{path}: no DataEnd record before the summary")

        def crc_of(lo: int, hi: int) -> int:
            crc, fh_pos = 0, fh.seek(lo)
            while fh_pos < hi:
                block = fh.read(min(1 << 20, hi - fh_pos))
                crc = zlib.crc32(block, crc)
                fh_pos += len(block)
            return crc

        data_crc = crc_of(0, data_end)
        summary_crc = crc_of(summary_start, foot + 25)  # through the Footer's summary_offset_start
        fh.seek(data_end + 9)
        fh.write(_U32.pack(data_crc))
        fh.seek(foot + 25)
        fh.write(_U32.pack(summary_crc))
