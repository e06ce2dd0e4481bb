"""``make figures``: every figure into ``analysis/out/``.

* Fig. 2 (the paper's 2-D illustration, drawn from :class:`amex.methods.AMEX` itself),
* Fig. 4 analogue (one Task-3 environment: reference plan and the methods' paths),
* Fig. 6 analogue (reference versus executed path with the goal positions as dots).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str] | None = None) -> int:
    """Draw the figures; print the files written."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    parser = argparse.ArgumentParser(prog="make figures", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "out")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    from analysis.fig2 import plot_fig2
    from analysis.fig4 import plot_fig4
    from analysis.fig6 import plot_fig6

    written = [*plot_fig2(args.out), *plot_fig4(args.out), *plot_fig6(args.out)]
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
