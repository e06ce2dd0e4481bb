"""``episodes.csv``: the one place episode results live, written row by row and read tolerantly.

Every row carries two hashes of the configuration that produced it:

* ``config_hash``: everything that determines the episode (task, method and its parameters, scenes,
  plan, controller, rates, seed, code version), not ``episodes``, ``log``, ``shards`` or
  ``shard`` (which environments a run executes, not what they compute). A run resumes by
  skipping the environments already recorded under the same hash. The method's parameters are
  hashed in the scene's units (:mod:`amex.core.scaling`) and the robot's start pose as resolved from
  the catalogue, so a value written another way hashes the same. An option added later is left
  out while it has the value that reproduces the earlier behaviour (``_ADDED_OPTIONS``).
* ``scene_hash``: the same without task and method, so rows of different methods with equal scene
  hashes ran on identical environments (the condition for paired comparisons).

Rows are written through :mod:`amex.core.durable`: a row is appended completely and fsynced, or the
file is cut back to its previous length and :class:`~amex.core.durable.WriteError` raised (a full
disk), so a killed or failed run leaves whole rows only and resumes once the cause is gone; a torn
last line (e.g. a power loss) is dropped on read. A zero-byte file counts as no rows (a fresh run).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

from amex.core.durable import append_durably, replace_durably
from amex.core.errors import StoreError
from amex.core.version import __version__
from amex.sim.metrics import COLUMNS, REQUIRED_COLUMNS, EpisodeResult

HASH_COLUMNS = ("config_hash", "scene_hash")
CSV_COLUMNS = COLUMNS + HASH_COLUMNS
_NOT_RESULTS = ("episodes", "log", "shards", "shard")  # which rows, not what they hold
# Options added after runs were recorded, with the value that reproduces the behaviour before
# them: at that value they are left out of the hashes, so adding an option does not orphan
# existing runs (they resume and tabulate as before); any other value is hashed as usual.
_ADDED_OPTIONS: dict[tuple[str, ...], object] = {
    ("perception", "preview"): 0.0,
    ("sim",): "dynamic",
    ("state_lag",): False,
    ("plan", "metric"): "identity",
    ("plan", "final_velocity_space"): "joint",
    ("plan", "solver"): "levenberg",
    ("controller", "metric"): "identity",
    ("controller", "drift"): True,
    ("controller", "joint_only"): False,
    ("scenario", "plane_reference"): False,
    ("implementation",): "ours",
    ("scenario", "reference_offset"): [0.385, 1.147, -0.131],
    ("robot", "urdf"): "",
    ("robot", "joints"): [],
    ("robot", "tcp_frame"): "",
    ("robot", "package_dirs"): [],
    ("robot", "torque_limit"): [],
    ("robot", "velocity_limit"): [],
    ("controller", "disturbance"): "none",
    ("controller", "observer_bandwidth"): 20.0,
    ("controller", "observer_limit"): 1.0,
    ("controller", "integral_gain"): 10.0,
    ("controller", "integral_limit"): 50.0,
}




def _without_neutral(spec: dict[str, Any]) -> dict[str, Any]:
    """``spec`` without the added options that have their neutral value (``_ADDED_OPTIONS``)."""
    spec = dict(spec)
    for path, neutral in _ADDED_OPTIONS.items():
        *sections, key = path
        node = spec
        for section in sections:
            sub = node.get(section)
            if not isinstance(sub, dict):
                break
            node[section] = node = dict(sub)
        else:
            if key in node and node[key] == neutral:
                del node[key]
    return spec


def _digest(spec: dict[str, Any]) -> str:
    spec = {**_without_neutral(spec), "amex_version": __version__}
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _spec(config: Any, leave_out: tuple[str, ...]) -> dict[str, Any]:
    """The hashed form of ``config`` (module notes), without the keys ``leave_out``."""
    spec = asdict(config)
    if hasattr(config, "method_config") and "method" not in leave_out:
        spec["method"] = asdict(config.method_config())
    robot = spec.get("robot")
    if isinstance(robot, dict) and not robot.get("q0"):
        from amex.robot import CATALOGUE

        known = CATALOGUE.get(robot.get("name", ""))
        if known is not None:
            robot["q0"] = list(known.q0)
    return {k: v for k, v in spec.items() if k not in (*_NOT_RESULTS, *leave_out)}


def config_hash(config: Any) -> str:
    """Hash of everything that determines an episode's result (see module docstring)."""
    return _digest(_spec(config, ()))


def scene_hash(config: Any) -> str:
    """Hash of the benchmark's shared settings: equal for all tasks and methods of one sweep."""
    return _digest(_spec(config, ("task", "method")))


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


def parse_bool(text: str, name: str = "value") -> bool:
    """A flag as written by :func:`format_value`: exactly ``0`` or ``1``, else ``ValueError``."""
    if text == "1":
        return True
    if text == "0":
        return False
    raise ValueError(f"{name}={text!r}, valid: 0 or 1")


def parse_result(row: dict[str, str]) -> EpisodeResult:
    """An :class:`EpisodeResult` from a csv row (as read by ``csv.DictReader``).

    The one parser of stored values (resume and ``make table`` alike): flags must be 0 or 1,
    integers integers; anything else raises ``ValueError`` naming the column.
    """
    values: dict[str, Any] = {}
    for f in fields(EpisodeResult):
        if f.name not in row and f.name not in REQUIRED_COLUMNS:
            continue  # a metric added after the file was written: its default (nan)
        text = row[f.name]
        if f.type in ("bool", bool):
            values[f.name] = parse_bool(text, f.name)
        elif f.type in ("int", int):
            try:
                values[f.name] = int(text)
            except ValueError:
                raise ValueError(f"{f.name}={text!r}, valid: an integer") from None
        elif f.type in ("float", float):
            values[f.name] = float(text)
        else:
            values[f.name] = text
    return EpisodeResult(**values)


def read_rows(path: Path) -> list[dict[str, str]]:
    """The complete rows of an episodes.csv; a torn last line is dropped; none for a 0-byte file.

    Raises :class:`StoreError` for a missing file, a foreign header or a malformed row before the
    last one.
    """
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as e:
        reason = e.strerror if isinstance(e, OSError) else "not text"
        raise StoreError(f"{path}: cannot read ({reason})") from e
    if not text:
        return []  # created, nothing written yet (e.g. a full disk): a fresh run
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines = lines[:-1]  # torn by an interrupted write
    reader = csv.reader(lines)
    try:
        header = next(reader)
    except StopIteration:
        raise StoreError(f"{path}: no header line") from None
    if tuple(header[: len(REQUIRED_COLUMNS)]) != REQUIRED_COLUMNS:
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
                f"this run {config_hash}); choose another hydra.run.dir (hydra.sweep.dir for -m)"
            )
        return rows

    def _rewrite(self, rows: list[dict[str, str]]) -> None:
        lines = [_line(list(CSV_COLUMNS))]
        lines += [_line([row.get(c, "nan") for c in CSV_COLUMNS]) for row in rows]
        replace_durably(self.path, "".join(lines).encode())

    def append(self, result: EpisodeResult) -> None:
        """Record ``result`` durably: the whole row, fsynced, or :class:`WriteError` and no row."""
        values = [format_value(v) for v in result.as_row().values()]
        append_durably(self.path, _line([*values, self.config_hash, self.scene_hash]).encode())
        self.done[result.env] = result
