"""Reading episode logs back, tolerantly: intact files through the index, cut files chunk by chunk.

:func:`read_log` first reads through the file's index (its summary, checked against its CRC),
every chunk checked against its own CRC and the data section against the CRC of its DataEnd
record, so no damaged byte of a chunk passes as intact content. Without a readable summary it
streams the file record by record (:class:`mcap.stream_reader.StreamReader`), again checking every
chunk's CRC on its own. Either way it tells two cases apart:

* **truncated**: the file does not end with the MCAP magic, because the writer was killed
  (SIGKILL, power loss) mid-chunk: every record before the cut is kept, i.e. all but the last
  ~64 KiB;
* **corrupt**: the file is complete but damaged inside (flipped bytes): a damaged chunk is skipped
  and reading goes on with the next one, so only that chunk's messages are lost; the summary's
  message count, when readable, says how many.

Short reads raise instead of being passed on, so a cut record is never returned as a shorter one.
:func:`amex.log.recover.recover` writes what was read as a new, indexed MCAP file.

JSON channels and amex's own protobuf channels (``amex.*`` schemas: ``/tcp``, ``/goal``,
``/command``, ``/method``; :mod:`amex.log.flat_proto`) are decoded when read, into dicts with
every field of the schema (None where a message has none); the Foxglove schemas' channels stay
bytes until :meth:`LogData.decoded` decodes them with their own schema (:mod:`amex.log.protobuf`,
no protobuf package needed); :meth:`LogData.joints` gives the joint states as arrays.
"""

from __future__ import annotations

import contextlib
import json
import struct
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from amex.core.errors import (
    CorruptLogError,
    EmptyLogError,
    LogError,
    LogNotFoundError,
    NotMcapError,
    TruncatedLogError,
)
from amex.log.flat_proto import FlatDecoder
from amex.log.protobuf import ProtobufSchema
from amex.log.records import MCAP_MAGIC, IndexedEnd, RawLog, read_indexed, read_stream


class ChannelInfo(NamedTuple):
    """One channel (topic) of a log."""

    topic: str
    schema_name: str
    message_encoding: str
    message_count: int


class LogMessage(NamedTuple):
    """One message: log time [ns] (simulation time) and data (decoded JSON, else bytes)."""

    log_time: int
    data: Any


@dataclass(frozen=True)
class LogData:
    """Everything read from one log file.

    Attributes:
        path: the file read.
        size: its size [bytes].
        channels: per topic, its schema, encoding and message count.
        messages: per topic, the messages in log-time order.
        metadata: MCAP metadata records by name; values parsed from JSON where they are JSON.
        truncated: True if the file was cut (read by streaming; see :attr:`note`).
        note: why the file counts as truncated or corrupt, and what was lost.
        corrupt: True if damaged chunks inside a complete file were skipped (see :attr:`note`).
    """

    path: Path
    size: int
    channels: dict[str, ChannelInfo]
    messages: dict[str, list[LogMessage]]
    metadata: dict[str, dict[str, Any]]
    truncated: bool = False
    note: str = ""
    corrupt: bool = False
    _raw: RawLog | None = field(default=None, repr=False, compare=False)
    _decoded: dict[str, list[LogMessage]] = field(default_factory=dict, repr=False, compare=False)

    @property
    def message_count(self) -> int:
        """Number of messages read (recovered, for a truncated file)."""
        return sum(c.message_count for c in self.channels.values())

    @property
    def damage(self) -> str:
        """``""`` for an intact file, else ``"truncated"``, ``"corrupt"`` or both."""
        flags = (("truncated", self.truncated), ("corrupt", self.corrupt))
        return " and ".join(word for word, flag in flags if flag)

    @property
    def is_amex_log(self) -> bool:
        """Whether amex wrote it (it has the ``episode`` metadata record or an amex channel)."""
        return "episode" in self.metadata or "/tcp" in self.channels

    @property
    def start_time(self) -> float:
        """Earliest log time [s] (simulation time), 0 without messages."""
        times = [m[0].log_time for m in self.messages.values() if m]
        return min(times) * 1e-9 if times else 0.0

    @property
    def end_time(self) -> float:
        """Latest log time [s] (simulation time), 0 without messages."""
        times = [m[-1].log_time for m in self.messages.values() if m]
        return max(times) * 1e-9 if times else 0.0

    @property
    def duration(self) -> float:
        """``end_time - start_time`` [s]."""
        return self.end_time - self.start_time

    @property
    def outcome(self) -> dict[str, Any] | None:
        """The ``outcome`` metadata record (or the ``/episode`` message); None if never written."""
        if "outcome" in self.metadata:
            return self.metadata["outcome"]
        episode = self.messages.get("/episode")
        if episode and isinstance(episode[-1].data, dict):
            return dict(episode[-1].data)
        return None

    def times(self, topic: str) -> np.ndarray:
        """Log times of ``topic``'s messages [s], shape (n,)."""
        return np.array([m.log_time for m in self.messages.get(topic, [])], dtype=float) * 1e-9

    def decoded(self, topic: str) -> list[LogMessage]:
        """``topic``'s messages with decoded data: JSON as read, protobuf through its schema.

        Protobuf messages become dicts (field name -> value; proto3 leaves out fields at their
        default, e.g. a zero coordinate); undecodable messages stay bytes. Cached.
        """
        messages = self.messages.get(topic, [])
        info = self.channels.get(topic)
        if info is None or info.message_encoding != "protobuf" or self._raw is None:
            return messages
        if info.schema_name.startswith("amex."):
            return messages  # amex's own messages: decoded when read
        if topic not in self._decoded:
            schema = next(
                (
                    self._raw.schemas.get(c.schema_id)
                    for c in self._raw.channels.values()
                    if c.topic == topic
                ),
                None,
            )
            decoded = list(messages)
            if schema is not None and schema.encoding == "protobuf":
                try:
                    decoder = ProtobufSchema(schema.data)
                except (ValueError, IndexError, struct.error, UnicodeDecodeError):
                    decoder = None  # a damaged schema: every message stays bytes
                if decoder is not None:
                    decoded = [_decoded(decoder, schema.name, m) for m in messages]
            self._decoded[topic] = decoded
        return self._decoded[topic]

    def joints(self, field: str, topic: str = "/joint_states") -> np.ndarray:
        """One field of the joint states over time, shape (n, joints).

        Args:
            field: ``position`` [rad], ``velocity`` [rad/s], ``acceleration`` [rad/s^2] or
                ``effort`` [N m].
            topic: the ``foxglove.JointStates`` channel.
        """
        rows = [
            [j.get(field, 0.0) for j in m.data.get("joints", [])]
            for m in self.decoded(topic)
            if isinstance(m.data, dict)
        ]
        width = max((len(r) for r in rows), default=0)
        out = np.full((len(rows), width), np.nan)
        for i, row in enumerate(rows):
            out[i, : len(row)] = row
        return out

    def reference_path(self) -> np.ndarray:
        """The reference plan's TCP positions (``/reference``), shape (N + 1, 3) [m], or (0, 3)."""
        messages = self.messages.get("/reference", [])
        data = messages[0].data if messages else None
        if isinstance(data, dict) and data.get("samples"):
            return np.array([s["position"] for s in data["samples"]], dtype=float).reshape(-1, 3)
        if isinstance(data, dict) and data.get("y"):  # logs before amex 0.1 kept y as a matrix
            return np.asarray(data["y"], dtype=float)[:, :3]
        return np.zeros((0, 3))

    def series(self, topic: str, key: str) -> np.ndarray:
        """``data[key]`` of every message of ``topic`` stacked, shape (n,) or (n, k).

        Missing or null values become NaN (so that rows stay aligned with :meth:`times`).
        """
        rows = []
        width = None
        for m in self.decoded(topic):
            value = m.data.get(key) if isinstance(m.data, dict) else None
            rows.append(value)
            if value is not None and width is None:
                width = len(value) if isinstance(value, list) else 0
        if width is None:
            return np.full(len(rows), np.nan)
        out = np.full((len(rows), width) if width else len(rows), np.nan)
        for i, value in enumerate(rows):
            if value is None:
                continue
            if width:
                out[i] = [np.nan if v is None else v for v in value]
            else:
                out[i] = np.nan if value is None else value
        return out


def _decoded(decoder: ProtobufSchema, name: str, message: LogMessage) -> LogMessage:
    """One protobuf message decoded, or left as bytes if it cannot be (the others still are)."""
    try:
        return LogMessage(message.log_time, decoder.decode(name, message.data))
    except (ValueError, IndexError, struct.error, UnicodeDecodeError, TypeError):
        return message


def _check_file(path: Path) -> int:
    """Size of ``path``, or the error that says why it is no log."""
    if not path.exists():
        raise LogNotFoundError(f"log file not found: {path}")
    if path.is_dir():
        raise LogError(f"{path} is a directory, not a log file")
    size = path.stat().st_size
    if size == 0:
        raise EmptyLogError(f"log file is empty (0 bytes): {path}")
    with open(path, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC[: len(head)] or (len(head) < len(MCAP_MAGIC) and size >= 8):
        raise NotMcapError(f"not an MCAP file (no MCAP magic bytes at the start): {path}")
    if len(head) < len(MCAP_MAGIC):
        raise TruncatedLogError(f"log file is truncated inside the MCAP magic ({size} B): {path}")
    return size


def _decode(
    raw: RawLog, path: Path, size: int, truncated: bool, note: str, corrupt: bool = False
) -> LogData:
    raw.messages.sort(key=lambda m: (m.log_time, m.channel_id, m.sequence))
    by_topic: dict[str, list[LogMessage]] = {c.topic: [] for c in raw.channels.values()}
    flat = {cid: _flat_decoder(raw, c) for cid, c in raw.channels.items()}
    for message in raw.messages:
        channel = raw.channels[message.channel_id]
        data: Any = message.data
        if channel.message_encoding == "json":
            with contextlib.suppress(ValueError):  # invalid JSON stays bytes
                data = json.loads(data)
        elif (decoder := flat[message.channel_id]) is not None:
            with contextlib.suppress(ValueError, IndexError):  # a damaged message stays bytes
                data = decoder.decode(data)
        by_topic[channel.topic].append(LogMessage(message.log_time, data))
    channels = {}
    for channel in raw.channels.values():
        schema = raw.schemas.get(channel.schema_id)
        channels[channel.topic] = ChannelInfo(
            channel.topic,
            schema.name if schema is not None else "",
            channel.message_encoding,
            len(by_topic[channel.topic]),
        )
    metadata: dict[str, dict[str, Any]] = {}
    for record in raw.metadata:
        metadata.setdefault(record.name, {}).update(
            {k: _parse(v) for k, v in record.metadata.items()}
        )
    return LogData(path, size, channels, by_topic, metadata, truncated, note, corrupt, raw)


def _flat_decoder(raw: RawLog, channel: Any) -> FlatDecoder | None:
    """The decoder of an amex protobuf channel (``amex.*`` schemas, :mod:`amex.log.flat_proto`)."""
    schema = raw.schemas.get(channel.schema_id)
    if channel.message_encoding != "protobuf" or schema is None or schema.encoding != "protobuf":
        return None
    if not schema.name.startswith("amex."):
        return None  # Foxglove's schemas: decoded on request (LogData.decoded)
    try:
        return FlatDecoder(schema.data, schema.name)
    except (ValueError, IndexError, struct.error, UnicodeDecodeError):
        return None  # a damaged schema: the messages stay bytes


def _parse(text: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        return text


def read_log(path: Path | str) -> LogData:
    """Read a log: intact files through the index, cut files up to their last complete chunk.

    Raises:
        LogNotFoundError, EmptyLogError, NotMcapError: the file is missing, empty or not MCAP.
        TruncatedLogError: the file was cut before its first complete chunk (nothing to read).
    """
    path = Path(path)
    size = _check_file(path)
    try:
        with open(path, "rb") as f:
            indexed = read_indexed(f, size)
            if indexed is not None:
                raw, end = indexed
                if not end.damaged and end.data_crc_ok:
                    return _decode(raw, path, size, False, "")
                return _damaged(raw, end, path, size)
            f.seek(max(size - len(MCAP_MAGIC), 0))
            complete = f.read(len(MCAP_MAGIC)) == MCAP_MAGIC and size > 2 * len(MCAP_MAGIC)
            raw, stream = read_stream(f)
    except OSError as e:
        raise LogError(f"cannot read {path}: {e.strerror or e}") from e
    truncated = bool(stream.stopped) and not complete
    notes = []
    if truncated:
        notes.append(f"cut at {size} bytes, in {stream.stopped}")
    if stream.damaged:
        notes.append(f"{stream.damaged} damaged chunk{'s' * (stream.damaged > 1)} skipped")
    if stream.stopped and complete:
        notes.append(f"unreadable from {stream.stopped} on")
    if stream.expected is not None and (stream.damaged or stream.stopped):
        notes.append(f"{len(raw.messages)} of {stream.expected} messages read")
    corrupt = bool(stream.damaged) or (bool(stream.stopped) and complete)
    note = "; ".join(notes) or "no summary section"
    if not raw.messages:
        if corrupt and not truncated:
            raise CorruptLogError(f"log file is corrupt ({note}), nothing to recover: {path}")
        raise TruncatedLogError(
            f"log file is truncated before its first complete chunk ({size} bytes), "
            f"nothing to recover: {path}"
        )
    return _decode(raw, path, size, truncated, note, corrupt)


def _damaged(raw: RawLog, end: IndexedEnd, path: Path, size: int) -> LogData:
    """A complete file whose summary holds but whose data section is damaged: corrupt."""
    notes = []
    if end.damaged:
        notes.append(f"{end.damaged} damaged chunk{'s' * (end.damaged > 1)} skipped")
    else:
        notes.append("damaged outside its chunks (data section CRC mismatch)")
    if end.expected is not None:
        notes.append(f"{len(raw.messages)} of {end.expected} messages read")
    note = "; ".join(notes)
    if not raw.messages:
        raise CorruptLogError(f"log file is corrupt ({note}), nothing to recover: {path}")
    return _decode(raw, path, size, False, note, True)


def topics_with_numbers(data: LogData) -> Iterable[str]:
    """The JSON and amex protobuf topics of ``data`` whose messages are objects (tables)."""
    for topic, info in sorted(data.channels.items()):
        ours = info.message_encoding == "json" or info.schema_name.startswith("amex.")
        if ours and any(isinstance(m.data, dict) for m in data.messages[topic]):
            yield topic
