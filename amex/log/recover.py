"""A damaged log's readable part, rewritten as a valid indexed MCAP file (``amex-log recover``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

from mcap.writer import CompressionType, Writer

from amex.core.errors import LogError, LogExistsError
from amex.log.reader import LogData, read_log


def recover(src: Path | str, dst: Path | str) -> LogData:
    """Rewrite the readable part of ``src`` as a valid, indexed MCAP file ``dst``.

    Schemas, channels, messages (in log-time order) and metadata records are copied unchanged;
    a metadata record ``recovery`` says where they came from. ``dst`` must not exist.

    Returns:
        What was read from ``src`` (``truncated`` tells whether it was cut).
    """
    src, dst = Path(src), Path(dst)
    data = read_log(src)
    if dst.exists():
        raise LogExistsError(f"output file {dst} already exists; not overwriting it")
    raw = data._raw
    if raw is None:  # pragma: no cover - read_log always keeps the records
        raise LogError(f"no records kept while reading {src}")
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(dst.name + ".part")
    try:
        with open(tmp, "wb") as f:
            writer = Writer(f, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
            writer.start(profile="", library="amex-log recover")
            schema_ids = {
                sid: writer.register_schema(s.name, s.encoding, s.data)
                for sid, s in sorted(raw.schemas.items())
            }
            channel_ids = {
                cid: writer.register_channel(
                    c.topic, c.message_encoding, schema_ids.get(c.schema_id, 0), dict(c.metadata)
                )
                for cid, c in sorted(raw.channels.items())
            }
            for record in raw.metadata:
                writer.add_metadata(record.name, dict(record.metadata))
            writer.add_metadata(
                "recovery",
                {
                    "source": json.dumps(str(src)),
                    "source_bytes": json.dumps(data.size),
                    "truncated": json.dumps(data.truncated),
                    "corrupt": json.dumps(data.corrupt),
                    "messages": json.dumps(len(raw.messages)),
                    "note": json.dumps(data.note),
                },
            )
            for m in raw.messages:
                writer.add_message(
                    channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence
                )
            writer.finish()
        if dst.exists():
            raise LogExistsError(f"output file {dst} appeared while writing; kept {tmp}")
        os.replace(tmp, dst)
    except OSError as e:
        raise LogError(f"cannot write {dst}: {e.strerror or e}") from e
    return data
