"""Reading ``episodes.csv`` files into one typed DataFrame, shards merged and checked.

Every analysis reads its episodes here: :func:`load_runs` takes every ``episodes.csv`` under a
directory, :func:`read_episodes` a given list of them (a study's cells). The shards of a cell
(``shards=K shard=I``, :mod:`amex.experiment.shards`) are merged into one; shards that overlap or
leave environments out are refused with one line naming them (:func:`check_shards`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from amex.core.errors import AmexError
from amex.experiment.shards import ShardError, check_cover, read_spec
from amex.experiment.store import HASH_COLUMNS, parse_result, read_rows

FLOAT_COLUMNS = (
    "final_distance",
    "final_time",
    "sum_sq_acc",
    "sum_sq_acc_paper",
    "int_sq_acc",
    "compute_time_median",
    "compute_time_mean",
    "compute_cpu_median",
    "compute_cpu_mean",
)


class TableError(AmexError):
    """The runs cannot make one table; the message names the file(s)."""


def duration_invariant_smoothness(sum_sq_acc, final_time):
    """``sum_sq_acc * final_time**3``: the sum of squared accelerations at equal duration.

    A motion executed k times slower has k^-2 the accelerations over k times the 1 kHz samples,
    so its sum of squared accelerations falls as k^-3 while this product stays the same
    (``docs/analysis.md``). A diagnostic, not one of the paper's metrics [rad^2 s^-1].
    """
    return sum_sq_acc * final_time**3


def load_runs(root: Path) -> pd.DataFrame:
    """All episodes under ``root`` as one DataFrame (a row per episode), typed.

    Raises:
        TableError: no such directory, no ``episodes.csv`` under it, or shards that do not fit.
        StoreError: an ``episodes.csv`` cannot be read (the message names it).
    """
    if not root.is_dir():
        raise TableError(f"{root}: no such directory (run amex-run first, or RUNS=DIR)")
    files = sorted(root.rglob("episodes.csv"))
    if not files:
        raise TableError(f"no episodes.csv under {root} (run amex-run first, or RUNS=DIR)")
    return read_episodes(files, f"every episodes.csv under {root} is empty")


def read_episodes(files: Sequence[Path], empty: str = "") -> pd.DataFrame:
    """The episodes of ``files`` as one DataFrame in environment order, with a ``file`` column.

    Rows repeated by another run of the same configuration are dropped. ``empty``: the message
    of the :class:`TableError` raised when no file holds a row (default: it names the files).
    """
    frames = []
    for path in files:
        rows = read_rows(path)
        if not rows:
            continue
        if "scene_hash" not in rows[0]:
            raise TableError(f"{path}: written by an older amex without configuration hashes")
        # typed by the store's own parser, as the resume reads them (read_rows checked every row)
        typed = [
            {
                **parse_result(r).as_row(),
                **{h: r[h] for h in HASH_COLUMNS},
                "code_hash": r.get("code_hash") or "",
            }
            for r in rows
        ]
        frame = pd.DataFrame(typed)
        frame["file"] = str(path)
        frames.append(frame)
    if not frames:
        raise TableError(empty or f"no episodes in {', '.join(str(f) for f in files)}")
    df = pd.concat(frames, ignore_index=True)
    check_shards(df)
    # environment order within a cell, whichever shard ran it: means add up in the same order
    df = df.sort_values("env", kind="stable", ignore_index=True)
    df = df.drop_duplicates(subset=["scene_hash", "config_hash", "task", "method", "env"])
    for col in ("task", "env", "seed"):
        df[col] = df[col].astype(int)
    for col in ("success", "success_005", "collided"):
        df[col] = df[col].astype(int).astype(bool)
    for col in FLOAT_COLUMNS:
        df[col] = df[col].astype(float)
    df["sum_sq_acc_t3"] = duration_invariant_smoothness(df.sum_sq_acc, df.final_time)
    return df


def check_shards(df: pd.DataFrame) -> None:
    """Refuse shards of one configuration that overlap or leave gaps.

    ``df`` holds the rows with their ``file``; the shard of each file is its ``shard.json``.

    Raises:
        TableError: the shards' problem, in one line (:func:`amex.experiment.shards.check_cover`).
    """
    for (config, task, method), g in df.groupby(["config_hash", "task", "method"], sort=False):
        files = {}
        for file, rows in g.groupby("file", sort=True):
            try:
                spec = read_spec(Path(str(file)).parent)
            except ShardError as e:
                raise TableError(str(e)) from e
            files[str(Path(str(file)).parent)] = (spec, {int(e) for e in rows.env})
        try:
            check_cover(f"task {task} {method} (config {str(config)[:8]})", files)
        except ShardError as e:
            raise TableError(str(e)) from e
