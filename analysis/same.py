"""Are two runs the same? Their episodes compared row by row, outside the timing columns.

``python -m analysis.same A B``: every episode of the runs (or sweeps, or shards) under ``A``
is matched with the episode of ``B`` of the same task, method, seed and environment, and every
column both rows have is compared exactly, except those that follow the machine's speed
(:data:`amex.sim.metrics.TIMING_COLUMNS`) and the bookkeeping (hashes, the file). It prints one
line per differing column (rows that differ, the largest relative difference) and a last line
``N cells, M rows compared: K rows differ outside the timing columns``; exit code 0 when no row
differs and every episode has its match, 1 otherwise, 2 for unreadable input. The check behind
"bit for bit" in the docs and the closing notes (docs/reproducibility.md).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import NamedTuple

import pandas as pd

from amex.app.argparsing import OneLineParser
from amex.experiment.store import StoreError
from amex.sim.metrics import TIMING_COLUMNS

from .episodes import TableError, load_runs

KEY = ("task", "method", "seed", "env")
#: Columns that are no result: where a row was written, and the configuration's fingerprints.
BOOKKEEPING = ("file", "scene_hash", "config_hash", "code_hash")


class Difference(NamedTuple):
    """What differs between two runs: per column, rows and largest relative difference."""

    cells: int
    rows: int
    only_a: int
    only_b: int
    columns: dict[str, tuple[int, float]]
    differing_rows: int


def compare(a: pd.DataFrame, b: pd.DataFrame) -> Difference:
    """Rows of ``a`` and ``b`` matched on :data:`KEY`, every shared result column compared."""
    merged = a.merge(b, on=list(KEY), how="outer", suffixes=("_a", "_b"), indicator=True)
    both = merged[merged["_merge"] == "both"]
    skip = set(TIMING_COLUMNS) | set(BOOKKEEPING) | set(KEY)
    shared = [c for c in a.columns if c in b.columns and c not in skip]
    columns: dict[str, tuple[int, float]] = {}
    any_row = pd.Series(False, index=both.index)
    for col in shared:
        x, y = both[f"{col}_a"], both[f"{col}_b"]
        same = (x == y) | (x.isna() & y.isna())
        if same.all():
            continue
        any_row |= ~same
        worst = 0.0
        for u, v in zip(x[~same], y[~same], strict=True):
            try:
                fu, fv = float(u), float(v)
            except (TypeError, ValueError):
                worst = math.inf
                continue
            scale = max(abs(fu), abs(fv))
            worst = max(worst, abs(fu - fv) / scale if scale > 0 else math.inf)
        columns[col] = (int((~same).sum()), worst)
    return Difference(
        cells=both.groupby(["task", "method", "seed"]).ngroups,
        rows=len(both),
        only_a=int((merged["_merge"] == "left_only").sum()),
        only_b=int((merged["_merge"] == "right_only").sum()),
        columns=columns,
        differing_rows=int(any_row.sum()),
    )


def main(argv: list[str] | None = None) -> int:
    """Compare the runs under two directories (module notes); the exit code."""
    parser = OneLineParser(prog="analysis.same", description=__doc__.splitlines()[0])
    parser.add_argument("a", type=Path, metavar="RUNS_A")
    parser.add_argument("b", type=Path, metavar="RUNS_B")
    args = parser.parse_args(argv)
    try:
        d = compare(load_runs(args.a), load_runs(args.b))
    except (TableError, StoreError) as e:
        print(f"analysis.same: error: {e}", file=sys.stderr)
        return 2
    for col, (rows, worst) in d.columns.items():
        print(f"{col}: {rows} rows differ, largest relative difference {worst:.3g}")
    if d.only_a or d.only_b:
        print(f"unmatched episodes: {d.only_a} only in {args.a}, {d.only_b} only in {args.b}")
    print(
        f"{d.cells} cells, {d.rows} rows compared: {d.differing_rows} rows differ outside the "
        "timing columns"
    )
    return 0 if not (d.differing_rows or d.only_a or d.only_b) else 1


if __name__ == "__main__":
    sys.exit(main())
