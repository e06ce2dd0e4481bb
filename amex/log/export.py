"""An episode's channels as tables, one CSV or Parquet file per topic (``amex-log export``)."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

from amex.log.files import refuse_existing, write_new
from amex.log.reader import LogData, topics_with_numbers


def export_tables(data: LogData, out_dir: Path, fmt: str = "csv") -> list[Path]:
    """Write each JSON or amex protobuf topic, and the joint states, as a table (``q_0``...).

    Every file is new and written whole (:func:`amex.log.files.write_new`); if any of them
    exists, nothing is written. Messages that could not be decoded are left out of their table:
    :func:`undecodable` counts them. Returns the files written (tables, then ``metadata.json``).
    """
    import pandas as pd

    tables: dict[str, Any] = {t: _table(data, t) for t in topics_with_numbers(data)}
    if data.channels.get("/joint_states"):
        tables["/joints"] = _joint_table(data)
    paths = {
        topic: out_dir / f"{topic.strip('/').replace('/', '_') or 'root'}.{fmt}" for topic in tables
    }
    meta = out_dir / "metadata.json"
    refuse_existing(*paths.values(), meta)
    written = []
    for topic, rows in tables.items():
        frame = pd.DataFrame(rows)
        buffer = io.BytesIO()
        if fmt == "csv":
            frame.to_csv(buffer, index=False)
        else:
            frame.to_parquet(buffer, index=False)
        write_new(paths[topic], buffer.getvalue())
        written.append(paths[topic])
    info = {"truncated": data.truncated, "corrupt": data.corrupt, "note": data.note}
    write_new(meta, (json.dumps(info | data.metadata, indent=2) + "\n").encode())
    written.append(meta)
    return written


def undecodable(data: LogData) -> dict[str, tuple[int, int]]:
    """Per exported topic, ``(left out, messages)`` where messages could not be decoded."""
    counts = {}
    for topic in topics_with_numbers(data):
        messages = data.messages[topic]
        bad = sum(1 for m in messages if not isinstance(m.data, dict))
        if bad:
            counts[topic] = (bad, len(messages))
    return counts


def _table(data: LogData, topic: str) -> list[dict[str, Any]]:
    """Rows of ``topic``: ``time`` [s] plus the flattened message (lists of lists: rows)."""
    rows: list[dict[str, Any]] = []
    for m in data.messages[topic]:
        if not isinstance(m.data, dict):
            continue
        nested = {k: v for k, v in m.data.items() if _is_matrix(v)}
        if nested:  # e.g. /reference: one row per sample
            for key, matrix in nested.items():
                for i, sample in enumerate(matrix):
                    flat = {"index": i, **_flatten(sample, key)}
                    if "dt" in m.data:
                        flat = {"time": i * m.data["dt"], **flat}
                    rows.append(flat)
            continue
        row: dict[str, Any] = {"time": m.log_time * 1e-9}
        for key, value in m.data.items():
            if isinstance(value, list):
                row.update({f"{key}_{j}": x for j, x in enumerate(value)})
            elif isinstance(value, dict):
                row[key] = json.dumps(value)
            else:
                row[key] = value
        rows.append(row)
    return rows


def _joint_table(data: LogData) -> dict[str, Any]:
    """``/joint_states`` as columns ``time, q_0.., qd_0.., qdd_0.., tau_0..``."""
    table: dict[str, Any] = {"time": data.times("/joint_states")}
    for prefix, field in (("q", "position"), ("qd", "velocity"), ("qdd", "acceleration"),
                          ("tau", "effort")):  # fmt: skip
        values = data.joints(field)
        table.update({f"{prefix}_{j}": values[:, j] for j in range(values.shape[1])})
    return table


def _is_matrix(value: Any) -> bool:
    """A list of lists or of objects (``/reference``'s samples)."""
    return isinstance(value, list) and bool(value) and isinstance(value[0], (list, dict))


def _flatten(sample: Any, key: str) -> dict[str, Any]:
    """One sample as columns: a list as ``key_0, key_1..``, an object's lists as ``name_0..``."""
    if isinstance(sample, list):
        return {f"{key}_{j}": x for j, x in enumerate(sample)}
    flat: dict[str, Any] = {}
    for name, value in sample.items():
        if isinstance(value, list):
            flat.update({f"{name}_{j}": x for j, x in enumerate(value)})
        else:
            flat[name] = value
    return flat
