"""``make figures``: every figure into ``analysis/out/``, from runs (none is simulated here).

* Fig. 5 as figures (:mod:`analysis.fig5`) from the runs under ``--runs`` (``RUNS=`` in make,
  default ``runs/``), one set per benchmark configuration;
* Fig. 2 (the paper's 2-D illustration, drawn from :class:`amex.methods.AMEX` itself);
* Fig. 4 (:mod:`analysis.fig4`) from the logged runs of ``amex-run -m experiment=fig4``
  (``--fig4``, default ``runs/fig4``) and Fig. 6 (:mod:`analysis.fig6`) from those of
  ``amex-run experiment=fig6`` (``--fig6``, default ``runs/fig6``): ``make figures`` runs both
  first;
* the robustness study's plots and report, redrawn from ``<runs>/robustness`` when its sweep is
  there (``make studies`` runs it).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from amex.app.argparsing import OneLineParser

from . import default_out


def main(argv: list[str] | None = None) -> int:
    """Draw the figures; print the files written."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    parser = OneLineParser(prog="make figures", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=default_out())
    parser.add_argument("--runs", type=Path, default=Path("runs"), help="default: runs/")
    parser.add_argument("--fig4", type=Path, default=Path("runs/fig4"), help="Fig. 4's runs")
    parser.add_argument("--fig6", type=Path, default=Path("runs/fig6"), help="Fig. 6's run")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    from amex.core.errors import AmexError
    from amex.experiment.store import StoreError

    from .episodes import TableError
    from .fig2 import plot_fig2
    from .fig4 import plot_fig4
    from .fig5 import plot_runs
    from .fig6 import plot_run

    written: list[Path] = []
    try:
        written += plot_runs(args.runs, args.out)
    except (TableError, StoreError) as e:
        print(f"make figures: note: no Fig. 5 ({e})", file=sys.stderr)
    written += plot_fig2(args.out)
    try:
        written += [*plot_fig4(args.fig4, args.out), *plot_run(args.fig6, args.out)]
    except AmexError as e:
        print(f"make figures: error: {e}", file=sys.stderr)
        return 2
    if (args.runs / "robustness" / "multirun.yaml").exists():
        from .robustness import write_outputs

        try:
            written += write_outputs(args.runs / "robustness", args.out)
        except AmexError as e:
            print(f"make figures: note: no robustness plots ({e})", file=sys.stderr)
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
