"""``make figures``: every figure into ``analysis/out/``.

* Fig. 5 as figures (:mod:`analysis.fig5`) from the runs under ``--runs`` (``RUNS=`` in make,
  default ``runs/``): per task the distributions of final time, smoothness and compute time per
  method, success with intervals, the paper's means marked; one set per benchmark configuration;
* Fig. 2 (the paper's 2-D illustration, drawn from :class:`amex.methods.AMEX` itself),
* Fig. 4 analogue (one Task-3 environment: reference plan and the methods' paths),
* Fig. 6 analogue (reference versus executed path with the goal positions as dots),
* the robustness study's plots and table, redrawn from ``<runs>/robustness`` when its runs exist
  (``make studies`` runs the studies: ~1.5 h on one core).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from amex.app.argparsing import OneLineParser

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    """Draw the figures; print the files written."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    parser = OneLineParser(prog="make figures", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "out")
    parser.add_argument("--runs", type=Path, default=Path("runs"), help="default: runs/")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    from amex.experiment.store import StoreError
    from analysis.fig2 import plot_fig2
    from analysis.fig4 import plot_fig4
    from analysis.fig5 import plot_runs
    from analysis.fig6 import plot_fig6
    from analysis.table import TableError

    written: list[Path] = []
    try:
        written += plot_runs(args.runs, args.out)
    except (TableError, StoreError) as e:
        print(f"make figures: note: no Fig. 5 ({e})", file=sys.stderr)
    written += [*plot_fig2(args.out), *plot_fig4(args.out), *plot_fig6(args.out)]
    runs = args.runs / "robustness"
    if runs.is_dir():
        from analysis.robustness import Study, write_outputs

        cells = [p for p in runs.iterdir() if (p / "episodes.csv").exists()]
        if cells:
            episodes = max(
                1, min((p / "episodes.csv").read_text().count("\n") - 1 for p in cells)
            )
            written += write_outputs(Study(episodes=episodes), runs, args.out)
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
