"""``amex-analysis``: the tables, figures and study reports, from an installed amex.

``amex-analysis table RUNS`` is ``make table``'s command, and so on: every report reads the
runs under a directory and writes into ``--out`` (default ``analysis/out`` under the current
directory). In a checkout, ``python -m analysis.<command>`` is the same.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence

#: command -> (module, what it writes)
COMMANDS = {
    "table": ("table", "the paper's Fig. 5 as tables from the runs under RUNS (make table)"),
    "compare": ("compare", "benchmarks side by side, e.g. original=DIR ours=DIR (make table)"),
    "figures": ("figures", "Fig. 5 plots and Fig. 2, 4, 6 analogues (make figures)"),
    "fig4": ("fig4", "Fig. 4 from the logs of `amex-run -m experiment=fig4`"),
    "fig5": ("fig5", "the Fig. 5 plots alone"),
    "fig6": ("fig6", "Fig. 6 from the logs of `amex-run experiment=fig6`"),
    "robustness": ("robustness", "the robustness study's report (`amex-run -m study=robustness`)"),
    "pr2": ("pr2", "the pr2_like study's report (`amex-run -m study=pr2_like`)"),
}
PROG = "amex-analysis"


def _usage() -> str:
    width = max(map(len, COMMANDS)) + 2
    rows = "\n".join(f"  {name:<{width}}{text}" for name, (_, text) in COMMANDS.items())
    return f"usage: {PROG} COMMAND [ARGS ...]   ({PROG} COMMAND --help for its options)\n\n{rows}\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Run one report command; its exit code (2 after a one-line error)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ("-h", "--help"):
        sys.stdout.write(_usage())
        return 0
    if args[0] == "--version":
        from amex import __version__

        sys.stdout.write(f"{PROG} {__version__}\n")
        return 0
    if args[0] not in COMMANDS:
        sys.stderr.write(
            f"{PROG}: error: invalid command {args[0]!r}; valid: {', '.join(COMMANDS)}\n"
        )
        return 2
    module = importlib.import_module(f"{__package__}.{COMMANDS[args[0]][0]}")
    code = module.main(args[1:])
    return int(code or 0)


if __name__ == "__main__":
    sys.exit(main())
