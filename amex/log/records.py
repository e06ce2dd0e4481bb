"""An MCAP file's records: through its index, or streamed past damage (for :mod:`.reader`).

:func:`read_indexed` uses the ``mcap`` package's seeking reader and gives up (None) on any
damage. :func:`read_stream` reads record by record from the start: a chunk whose content is
damaged (CRC mismatch, undecompressible) is skipped and reading goes on; where the top-level
stream itself breaks (a cut, an unreadable record header) it stops and says why. Short reads
raise instead of being passed on, so a cut record is never returned as a shorter one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import IO, Any, NamedTuple

from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, Message, Metadata, Schema, Statistics
from mcap.stream_reader import StreamReader, breakup_chunk

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


def read_indexed(f: IO[bytes]) -> RawLog | None:
    """All records through the summary index; None if the file has no readable summary."""
    try:
        reader = SeekingReader(f)
        if reader.get_summary() is None:
            return None
        raw = RawLog()
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if schema is not None:
                raw.schemas.setdefault(schema.id, schema)
            raw.channels.setdefault(channel.id, channel)
            raw.messages.append(message)
        raw.metadata = list(reader.iter_metadata())
        summary = reader.get_summary()
        if summary is not None:  # channels without messages still count as channels
            for sid, schema in summary.schemas.items():
                raw.schemas.setdefault(sid, schema)
            for cid, channel in summary.channels.items():
                raw.channels.setdefault(cid, channel)
        return raw
    except Exception:  # any failure: fall back to the tolerant stream
        return None


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
