"""A study's sweep as it ran: its jobs, each matched to its run directories and episodes.

A study is a sweep (``conf/study/<name>.yaml``, run by ``amex-run -m study=<name>``). Its
directory holds ``multirun.yaml`` (the study as composed, with ``hydra.sweeper.params``,
``hydra.sweeper.grids`` and the command line as the sweep ran them) and a directory per job
with ``.hydra/overrides.yaml``, ``.hydra/config.yaml`` and ``episodes.csv``. :func:`read_sweep`
expands the jobs as the sweeper does (:mod:`analysis.overrides`), finds each job's directories
by their overrides (every shard of it) and reads its episodes; a job without a complete run is
refused in one line. The reports learn what each cell is from these files alone.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from amex.core.errors import AmexError

from .episodes import read_episodes
from .overrides import from_mapping, job_of, normalized, product

#: Overrides that say which environments a job runs, not what its cell is.
SHARD_KEYS = ("shard",)


class StudyError(AmexError):
    """A study's runs are missing or incomplete; the message says which and how to fix it."""


def config_value(config: Mapping[str, Any], key: str, default: Any = None) -> Any:
    """The value at the dotted ``key`` of a configuration read from YAML (``default`` if none)."""
    node: Any = config
    for part in key.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return default
        node = node[part]
    return node


def read_yaml(path: Path) -> Any:
    """The content of a YAML file that a run wrote.

    Raises:
        StudyError: the file is missing or is not YAML.
    """
    try:
        return yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise StudyError(f"{path}: cannot be read ({e})") from e


@dataclass(frozen=True)
class Cell:
    """One job of a sweep and what its runs recorded.

    Attributes:
        grids: the grids of the study that declare it, in declaration order ("" without grids).
        overrides: its overrides, ``key -> value text`` in declaration order (command line
            included; ``shard`` aside).
        config: its ``.hydra/config.yaml``.
        dirs: its run directories (one per shard).
        episodes: its environments ``0 .. episodes - 1``, in order.
    """

    grids: tuple[str, ...]
    overrides: dict[str, str]
    config: dict[str, Any]
    dirs: tuple[Path, ...]
    episodes: pd.DataFrame

    def get(self, key: str, default: Any = None) -> Any:
        """The cell's configuration value at the dotted ``key``."""
        return config_value(self.config, key, default)

    @property
    def logged(self) -> bool:
        """Whether the cell logged its episodes (``log=full``)."""
        return self.get("log") == "full"


@dataclass(frozen=True)
class Sweep:
    """A study's sweep: its composed configuration and its cells.

    Attributes:
        runs: the sweep directory.
        config: the study as composed before any job's overrides (``multirun.yaml``).
        arguments: the command line's overrides (``study=...``, ``episodes=...``, ...).
        cells: every job once, in declaration order.
        grids: each grid's cells in its product's order, the grids in declaration order
            (one grid named "" without grids).
    """

    runs: Path
    config: dict[str, Any]
    arguments: tuple[str, ...]
    cells: tuple[Cell, ...]
    grids: dict[str, tuple[Cell, ...]]

    @property
    def grid_names(self) -> tuple[str, ...]:
        """The grids in declaration order."""
        return tuple(self.grids)

    def grid(self, name: str) -> tuple[Cell, ...]:
        """The cells of grid ``name``, in its product's order."""
        return self.grids[name]

    def changed(self, cell: Cell, leave_out: Sequence[str] = ("task", "method")) -> list[str]:
        """The cell's own overrides that change the study's configuration, as ``key=value``.

        Leaves out the command line's, the keys ``leave_out`` and those that set the value the
        study has anyway.
        """
        shared = {o.split("=", 1)[0].lstrip("+~") for o in self.arguments}
        out = []
        for key, text in cell.overrides.items():
            if key in shared or key in leave_out:
                continue
            if normalized({key: text})[key] != config_value(self.config, key, object()):
                out.append(f"{key}={text}")
        return out


def declared_jobs(sweeper: Mapping[str, Any], arguments: Sequence[str]) -> list[tuple[str, dict]]:
    """``(grid name, job)`` of every job the sweeper declares, as :func:`sweep_jobs` of
    :mod:`amex.app.sweeps` forms them: one product per grid of the params, grid and command line.
    """
    base = from_mapping(sweeper.get("params"))
    grids = sweeper.get("grids") or {"": {}}
    return [
        (name, job)
        for name, grid in grids.items()
        for job in product([*base, *from_mapping(grid), *arguments])
    ]


def _run_dirs(runs: Path) -> list[tuple[Path, dict[str, Any]]]:
    """Every job directory under ``runs`` with its normalized overrides (``shard`` aside)."""
    found = []
    for path in sorted(runs.rglob("overrides.yaml")):
        if path.parent.name != ".hydra" or not (path.parent.parent / "episodes.csv").exists():
            continue
        job = job_of(str(o) for o in read_yaml(path) or [])
        found.append((path.parent.parent, normalized(job, SHARD_KEYS)))
    return found


def _cell(name: str, job: dict[str, str], dirs: list[Path], runs: Path) -> Cell:
    """The cell of ``job`` from its directories; StudyError if a run is missing or incomplete."""
    what = " ".join(f"{k}={v}" for k, v in job.items() if k != "study") or "(the defaults)"
    if not dirs:
        raise StudyError(
            f"{runs}: no runs of cell {what}; run the study's sweep (the same command resumes)"
        )
    config = read_yaml(dirs[0] / ".hydra" / "config.yaml") or {}
    count = int(config.get("episodes", 0))
    rows = read_episodes([d / "episodes.csv" for d in dirs], f"{runs}: no episodes of {what}")
    rows = rows[rows.env < count].sort_values("env", kind="stable").reset_index(drop=True)
    if rows.config_hash.nunique() > 1:
        raise StudyError(f"{runs}: cell {what} holds episodes of several configurations")
    if len(rows) < count:
        raise StudyError(
            f"{runs}: {len(rows)} of the {count} environments of cell {what}; run the study's "
            "sweep (the same command resumes)"
        )
    return Cell((name,), job, config, tuple(dirs), rows)


def read_sweep(runs: Path, study: str) -> Sweep:
    """The sweep of ``study`` in ``runs``, every cell with its episodes.

    Raises:
        StudyError: no sweep there, or a cell without a complete run.
        TableError: an ``episodes.csv`` cannot be read, or its shards do not fit together.
    """
    record = runs / "multirun.yaml"
    if not record.exists():
        raise StudyError(f"{runs}: no sweep there; run `amex-run -m study={study}`")
    composed = read_yaml(record) or {}
    hydra = composed.pop("hydra", None) or {}
    arguments = tuple(str(o) for o in config_value(hydra, "overrides.task", []) or [])
    if not any(o == f"study={study}" for o in arguments):
        raise StudyError(f"{record}: not a sweep of study={study} ({' '.join(arguments)})")
    directories = _run_dirs(runs)
    cells: list[Cell] = []
    members: dict[str, list[int]] = {}
    for name, job in declared_jobs(hydra.get("sweeper") or {}, arguments):
        key = normalized(job, SHARD_KEYS)
        same = next((i for i, c in enumerate(cells) if normalized(c.overrides) == key), None)
        if same is None:
            dirs = [path for path, overrides in directories if overrides == key]
            own = {k: v for k, v in job.items() if k not in SHARD_KEYS}
            cells.append(_cell(name, own, dirs, runs))
            same = len(cells) - 1
        elif name not in cells[same].grids:  # declared by an earlier grid too: it ran once
            cells[same] = replace(cells[same], grids=(*cells[same].grids, name))
        members.setdefault(name, []).append(same)
    grids = {name: tuple(cells[i] for i in index) for name, index in members.items()}
    return Sweep(runs, composed, arguments, tuple(cells), grids)
