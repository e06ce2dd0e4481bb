"""An episode's channels as tables, one CSV or Parquet file per topic (``amex-log export``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from amex.log.reader import LogData, topics_with_numbers


def export_tables(data: LogData, out_dir: Path, fmt: str = "csv") -> list[Path]:
    """Write each JSON topic, and the joint states, as a table (lists flattened: ``q_0``...).

    Returns the files written (the tables, then ``metadata.json``).
    """
    import pandas as pd

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    tables: dict[str, Any] = {t: _table(data, t) for t in topics_with_numbers(data)}
    if data.channels.get("/joint_states"):
        tables["/joints"] = _joint_table(data)
    for topic, rows in tables.items():
        frame = pd.DataFrame(rows)
        name = topic.strip("/").replace("/", "_") or "root"
        path = out_dir / f"{name}.{fmt}"
        if fmt == "csv":
            frame.to_csv(path, index=False)
        else:
            frame.to_parquet(path, index=False)
        written.append(path)
    meta = out_dir / "metadata.json"
    meta.write_text(
        json.dumps(
            {"truncated": data.truncated, "corrupt": data.corrupt, "note": data.note}
            | data.metadata,
            indent=2,
        )
        + "\n"
    )
    written.append(meta)
    return written


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
