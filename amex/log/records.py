"""An MCAP file's records: through its index, or streamed past damage (for :mod:`.reader`).

:func:`read_indexed` reads every chunk the summary indexes at its offset and checks it against
its own CRC (a damaged chunk is skipped, the others are read), after checking the summary's CRC;
the data section's CRC (DataEnd) says whether anything else is damaged. Without a valid summary
it gives up (None). :func:`read_stream` reads record by record from the start: a chunk whose
content is damaged (CRC mismatch, undecompressible) is skipped and reading goes on; where the
top-level stream itself breaks (a cut, an unreadable record header) it stops and says why.
Short reads raise instead of being passed on, so a cut record is never returned as a shorter one.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from typing import IO, Any, NamedTuple

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    Footer,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
)
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.summary import Summary

MCAP_MAGIC = b"\x89MCAP0\r\n"


@dataclass
class RawLog:
    """Records as read (what :func:`amex.log.reader.recover` rewrites)."""

    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)
    metadata: list[Metadata] = field(default_factory=list)


class _ExactReader:
    """A file wrapper whose short reads raise: the mcap stream reader would accept them."""

    def __init__(self, f: IO[bytes]) -> None:
        self._f = f

    def read(self, n: int = -1) -> bytes:
        data = self._f.read(n)
        if n > 0 and len(data) != n:
            raise EOFError(f"file ends {n - len(data)} bytes into a record")
        return data


class IndexedEnd(NamedTuple):
    """What reading through the index found besides the records.

    Attributes:
        damaged: chunks skipped because their content failed its CRC or did not decompress.
        chunks: chunks the summary indexes.
        data_crc_ok: the data section's CRC (in its DataEnd record) matches its bytes, or the
            writer recorded none (0): False means something in the data section is damaged,
            inside a chunk or between chunks.
        expected: the summary's message count (statistics), if it has one.
    """

    damaged: int
    chunks: int
    data_crc_ok: bool
    expected: int | None


_FOOTER_SIZE = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
_DATA_END_SIZE = 1 + 8 + 4  # opcode, length, data_section_crc


def _crc_of(f: IO[bytes], start: int, stop: int) -> int:
    """CRC-32 of the bytes ``[start, stop)`` of ``f``, read in 1 MiB blocks."""
    f.seek(start)
    crc = 0
    left = stop - start
    while left > 0:
        block = f.read(min(left, 1 << 20))
        if not block:
            raise EOFError("file ends inside the range of a CRC")
        crc = zlib.crc32(block, crc)
        left -= len(block)
    return crc


def _summary(f: IO[bytes], size: int) -> tuple[Summary, int] | None:
    """The summary section and where it starts, if present and its CRC holds."""
    if size < 2 * len(MCAP_MAGIC) + _FOOTER_SIZE:
        return None
    f.seek(size - len(MCAP_MAGIC))
    if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
        return None
    footer_at = size - len(MCAP_MAGIC) - _FOOTER_SIZE
    f.seek(footer_at)
    head = f.read(9)
    if head[:1] != bytes([Opcode.FOOTER]) or struct.unpack("<Q", head[1:])[0] != 20:
        return None
    footer = Footer.read(ReadDataStream(f))
    start = footer.summary_start
    if not len(MCAP_MAGIC) < start < footer_at:
        return None
    if footer.summary_crc and footer.summary_crc != _crc_of(f, start, size - len(MCAP_MAGIC) - 4):
        return None
    f.seek(start)
    summary = Summary()
    for record in StreamReader(_ExactReader(f), skip_magic=True).records:  # type: ignore[arg-type]
        if isinstance(record, Footer):
            break
        if isinstance(record, Statistics):
            summary.statistics = record
        elif isinstance(record, Schema):
            summary.schemas[record.id] = record
        elif isinstance(record, Channel):
            summary.channels[record.id] = record
        elif isinstance(record, ChunkIndex):
            summary.chunk_indexes.append(record)
        elif isinstance(record, MetadataIndex):
            summary.metadata_indexes.append(record)
    return summary, start


def _data_crc_ok(f: IO[bytes], summary_start: int) -> bool:
    """Whether the data section (magic to DataEnd) has the CRC its DataEnd record states."""
    at = summary_start - _DATA_END_SIZE
    f.seek(at)
    head = f.read(9)
    if head[:1] != bytes([Opcode.DATA_END]) or struct.unpack("<Q", head[1:])[0] != 4:
        return False
    (stated,) = struct.unpack("<I", f.read(4))
    return stated == 0 or stated == _crc_of(f, 0, at)


def _record_at(f: IO[bytes], offset: int, kind: type) -> Any:
    """The record of type ``kind`` at ``offset`` (raises on anything else)."""
    f.seek(offset)
    reader = StreamReader(_ExactReader(f), skip_magic=True, emit_chunks=True)  # type: ignore[arg-type]
    record = next(iter(reader.records))
    if not isinstance(record, kind):
        raise ValueError(f"expected a {kind.__name__} at byte {offset}")
    return record


def read_indexed(f: IO[bytes], size: int) -> tuple[RawLog, IndexedEnd] | None:
    """All records through the summary index, each chunk checked against its own CRC.

    None if the file has no summary, or its summary fails its CRC (then only streaming can read
    it). A chunk whose content fails its CRC or does not decompress is skipped and counted;
    the data section's CRC says whether anything else in it is damaged.
    """
    try:
        found = _summary(f, size)
        if found is None:
            return None
        summary, summary_start = found
        data_crc_ok = _data_crc_ok(f, summary_start)
    except Exception:  # any unreadable part of the summary: fall back to streaming
        return None
    raw = RawLog(schemas=dict(summary.schemas), channels=dict(summary.channels))
    damaged = 0
    for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        try:
            chunk = _record_at(f, index.chunk_start_offset, Chunk)
            inner = list(breakup_chunk(chunk, validate_crc=True))
        except Exception:  # a CRC mismatch, undecompressible or unreadable: skip this chunk
            damaged += 1
            continue
        for record in inner:
            _keep(raw, record)
    for entry in summary.metadata_indexes:
        try:
            raw.metadata.append(_record_at(f, entry.offset, Metadata))
        except Exception:  # a damaged metadata record is lost; the data CRC tells
            data_crc_ok = False
    expected = summary.statistics.message_count if summary.statistics is not None else None
    return raw, IndexedEnd(damaged, len(summary.chunk_indexes), data_crc_ok, expected)


class StreamEnd(NamedTuple):
    """What streaming read besides the records: where and why it stopped, what it skipped."""

    stopped: str  # why the top-level stream broke ("" if it reached the footer)
    damaged: int  # chunks skipped because their content was damaged
    expected: int | None  # the summary's message count, if its statistics record was read


def _keep(raw: RawLog, record: Any) -> None:
    if isinstance(record, Schema):
        raw.schemas[record.id] = record
    elif isinstance(record, Channel):
        raw.channels[record.id] = record
    elif isinstance(record, Message):
        if record.channel_id in raw.channels:
            raw.messages.append(record)
    elif isinstance(record, Metadata):
        raw.metadata.append(record)


def read_stream(f: IO[bytes]) -> tuple[RawLog, StreamEnd]:
    """Every readable record: damaged chunks skipped, reading stops where the stream breaks."""
    raw = RawLog()
    damaged = 0
    expected = None
    f.seek(len(MCAP_MAGIC))
    reader = StreamReader(_ExactReader(f), skip_magic=True, emit_chunks=True)  # type: ignore[arg-type]
    try:
        for record in reader.records:
            if isinstance(record, Chunk):
                try:
                    inner = list(breakup_chunk(record, validate_crc=True))
                except Exception:  # a CRC mismatch or undecompressible data: skip this chunk
                    damaged += 1
                    continue
                for r in inner:
                    _keep(raw, r)
            elif isinstance(record, Statistics):
                expected = record.message_count
            else:
                _keep(raw, record)
    except Exception as e:  # a cut or unreadable record ends the readable part
        return raw, StreamEnd(_reason(e), damaged, expected)
    return raw, StreamEnd("", damaged, expected)


def _reason(error: Exception) -> str:
    """Why streaming stopped, in words."""
    text = str(error)
    if "18446744073709551615" in text:  # the writer's placeholder length of an open chunk
        return "an unfinished chunk"
    if isinstance(error, EOFError) or type(error).__name__ == "EndOfFile":
        return "a record cut short"
    if "CRC" in type(error).__name__ or "crc" in text.lower():
        return "a damaged chunk (CRC mismatch)"
    return f"{type(error).__name__}: {text}"[:200]
