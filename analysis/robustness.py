"""``python -m analysis.robustness``: the robustness study's report from its sweep's runs.

Reads the runs of ``amex-run -m study=robustness`` (``conf/study/robustness.yaml``, in
``runs/robustness/``; :mod:`analysis.robustness_study`) and runs no episode. Writes into
``analysis/out/``: ``robustness.md`` (:mod:`analysis.robustness_report`), ``robustness.csv`` (one
row per cell and part) and ``robustness_speed.png``, ``robustness_noise.png``
(:mod:`analysis.robustness_plot`). The findings: ``docs/studies.md``.

Usage: ``python -m analysis.robustness [RUNS] [--quick] [--out DIR]`` (RUNS: runs/robustness).
"""

from __future__ import annotations

import os
from pathlib import Path

from amex.app.argparsing import OneLineParser

from . import default_out
from .robustness_plot import plot_sweep
from .robustness_report import render
from .robustness_study import aggregate, comparisons, read_study


def write_outputs(runs: Path, out_dir: Path, quick: bool = False) -> list[Path]:
    """Read the study's runs and write the report, the CSV and the two plots."""
    study, episodes = read_study(runs)
    cells = aggregate(study, episodes)
    pairs = comparisons(study, episodes)
    out_dir.mkdir(parents=True, exist_ok=True)
    md = out_dir / "robustness.md"
    csv = out_dir / "robustness.csv"
    failed = {
        name: sorted(int(e) for e in g.env[~g.success]) for name, g in episodes.groupby("cell")
    }
    md.write_text(render(study, cells, pairs, quick, failed))
    tmp = csv.with_suffix(".csv.tmp")
    cells.to_csv(tmp, index=False)
    os.replace(tmp, csv)
    written = [md, csv]
    for part in ("speed", "noise"):
        written.append(plot_sweep(study, cells, part, out_dir / f"robustness_{part}.png"))
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line (see the module docstring)."""
    from amex.core.errors import AmexError

    from . import print_written

    parser = OneLineParser(prog="python -m analysis.robustness", description=__doc__)
    parser.add_argument("runs", nargs="?", type=Path, default=Path("runs/robustness"))
    parser.add_argument("--quick", action="store_true", help="title the report a smoke run")
    parser.add_argument("--out", type=Path, default=default_out())
    args = parser.parse_args(argv)
    return print_written(
        "python -m analysis.robustness",
        lambda: write_outputs(args.runs, args.out, quick=args.quick),
        (AmexError,),
    )


if __name__ == "__main__":
    raise SystemExit(main())
