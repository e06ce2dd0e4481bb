"""``episodes.csv``: the one place episode results live, written row by row and read tolerantly.

Every row carries two hashes of the configuration that produced it:

* ``config_hash``: everything that determines the episode (task, method and its parameters, scenes,
  plan, controller, rates, seed, code version), not ``episodes`` or ``log``. A run resumes by
  skipping the environments already recorded under the same hash. An option added later is left
  out while it has the value that reproduces the earlier behaviour (``_ADDED_OPTIONS``).
* ``scene_hash``: the same without task and method, so rows of different methods with equal scene
  hashes ran on identical environments (the condition for paired comparisons).

A row is appended with a single ``write`` of the complete line on an ``O_APPEND`` descriptor and
fsynced, so a killed run leaves whole rows; a torn last line (e.g. a full disk) is dropped on read.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import amex
from amex.errors import AmexError
from amex.metrics import COLUMNS, EpisodeResult

HASH_COLUMNS = ("config_hash", "scene_hash")
CSV_COLUMNS = COLUMNS + HASH_COLUMNS
_NOT_RESULTS = ("episodes", "log")
# Options added after runs were recorded, with the value that reproduces the behaviour before
# them: at that value they are left out of the hashes, so adding an option does not orphan
# existing runs (they resume and tabulate as before); any other value is hashed as usual.
_ADDED_OPTIONS: dict[tuple[str, str], object] = {
    ("perception", "preview"): 0.0,
    ("controller", "disturbance"): "none",
    ("controller", "observer_bandwidth"): 20.0,
    ("controller", "observer_limit"): 1.0,
    ("controller", "integral_gain"): 10.0,
    ("controller", "integral_limit"): 50.0,
}


class StoreError(AmexError):
    """An episodes.csv cannot be used; the message names the file."""


def _digest(spec: dict[str, Any]) -> str:
    for (section, key), neutral in _ADDED_OPTIONS.items():
        sub = spec.get(section)
        if isinstance(sub, dict) and key in sub and sub[key] == neutral:
            spec = {**spec, section: {k: v for k, v in sub.items() if k != key}}
    spec = {**spec, "amex_version": amex.__version__}
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def config_hash(config: Any) -> str:
    """Hash of everything that determines an episode's result (see module docstring)."""
    spec = {k: v for k, v in asdict(config).items() if k not in _NOT_RESULTS}
    return _digest(spec)


def scene_hash(config: Any) -> str:
    """Hash of the benchmark's shared settings: equal for all tasks and methods of one sweep."""
    spec = {
        k: v for k, v in asdict(config).items() if k not in (*_NOT_RESULTS, "task", "method")
    }
    return _digest(spec)


def format_value(value: object) -> str:
    """CSV text of a metric: ``repr`` of floats (round-trips bit for bit), 0/1 for booleans."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def _line(values: list[str]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


def parse_result(row: dict[str, str]) -> EpisodeResult:
    """An :class:`EpisodeResult` from a csv row (as read by ``csv.DictReader``)."""
    values: dict[str, Any] = {}
    for f in fields(EpisodeResult):
        text = row[f.name]
        if f.type in ("bool", bool):
            values[f.name] = text == "1"
        elif f.type in ("int", int):
            values[f.name] = int(text)
        elif f.type in ("float", float):
            values[f.name] = float(text)
        else:
            values[f.name] = text
    return EpisodeResult(**values)


def read_rows(path: Path) -> list[dict[str, str]]:
    """The complete rows of an episodes.csv; a torn last line is dropped.

    Raises :class:`StoreError` for a missing/empty file, a foreign header or a malformed row
    before the last one.
    """
    try:
        text = path.read_text()
    except OSError as e:
        raise StoreError(f"{path}: cannot read ({e.strerror})") from e
    if not text.strip():
        raise StoreError(f"{path}: empty file, not an episodes.csv")
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines = lines[:-1]  # torn by an interrupted write
    reader = csv.reader(lines)
    try:
        header = next(reader)
    except StopIteration:
        raise StoreError(f"{path}: no header line") from None
    if tuple(header[: len(COLUMNS)]) != COLUMNS:
        raise StoreError(f"{path}: not an amex episodes.csv (header {','.join(header[:4])}...)")
    rows = []
    for lineno, values in enumerate(reader, start=2):
        if len(values) != len(header):
            raise StoreError(f"{path}:{lineno}: {len(values)} fields, expected {len(header)}")
        row = dict(zip(header, values, strict=True))
        try:
            parse_result(row)
        except (KeyError, ValueError) as e:
            raise StoreError(f"{path}:{lineno}: malformed row ({e})") from e
        rows.append(row)
    return rows


class EpisodeStore:
    """Append-only episodes.csv of one run directory, resumable by config hash.

    Args:
        path: the csv file.
        config_hash: hash of the run's configuration.
        scene_hash: hash of its scenes.
    """

    def __init__(self, path: Path, config_hash: str, scene_hash: str) -> None:
        self.path = path
        self.config_hash = config_hash
        self.scene_hash = scene_hash
        self.done: dict[int, EpisodeResult] = {}
        if path.exists() and path.stat().st_size > 0:
            rows = self.check(path, config_hash)
            self.done = {int(r["env"]): parse_result(r) for r in rows}
            self._rewrite(rows)  # drops a torn last line, keeps every complete row
        else:
            self._rewrite([])

    @staticmethod
    def check(path: Path, config_hash: str) -> list[dict[str, str]]:
        """The rows of ``path``; :class:`StoreError` if any comes from another configuration."""
        rows = read_rows(path)
        foreign = {r.get("config_hash", "") for r in rows} - {config_hash}
        if foreign:
            raise StoreError(
                f"{path} holds episodes of another configuration (hash {sorted(foreign)[0]}, "
                f"this run {config_hash}); choose another directory with hydra.run.dir=..."
            )
        return rows

    def _rewrite(self, rows: list[dict[str, str]]) -> None:
        tmp = self.path.with_suffix(".csv.tmp")
        with open(tmp, "w") as f:
            f.write(_line(list(CSV_COLUMNS)))
            for row in rows:
                f.write(_line([row[c] for c in CSV_COLUMNS]))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)

    def append(self, result: EpisodeResult) -> None:
        """Record ``result`` durably (one write, fsync)."""
        values = [format_value(v) for v in result.as_row().values()]
        data = _line([*values, self.config_hash, self.scene_hash]).encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        self.done[result.env] = result
