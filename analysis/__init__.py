"""Tables, figures and study reports from the runs' ``episodes.csv`` files (and logs)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path


def default_out() -> Path:
    """Where tables, figures and reports go unless ``--out`` says so: ``analysis/out`` here.

    Under the current directory (in a checkout: the repository's ``analysis/out``), never in
    the installed package.
    """
    return Path.cwd() / "analysis" / "out"


def write_report(out_dir: Path, name: str, text: str) -> Path:
    """``text`` as ``out_dir/name``, replaced atomically (a regenerated report); its path."""
    from amex.core.durable import replace_durably

    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / name
    replace_durably(path, text.encode())
    return path


def print_written(
    prog: str, write: Callable[[], Sequence[Path]], errors: tuple[type[Exception], ...]
) -> int:
    """A report's command line: run ``write`` and print each path it wrote.

    Returns the exit code: 0, or 2 after one line ``<prog>: error: ...`` on stderr for the
    expected ``errors``.
    """
    try:
        written = write()
    except errors as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    for path in written:
        print(path)
    return 0
