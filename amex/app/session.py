"""The command's own state: when it started, where it writes, and the last line it prints.

:data:`STARTED` is taken when the command starts (this module is imported first), for the sweep's
closing line; :data:`OUTPUT` holds the run or sweep directory once known; :func:`closing_line`
says how a stopped or failed command ended, with the number of episodes kept.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any, NoReturn

from amex.core.errors import AmexError, JobFailed

STARTED = time.perf_counter()
#: Where this process's run or sweep writes (``"dir"``), for the closing line.
OUTPUT: dict[str, Path] = {}
PROG = "amex-run"


def say(line: str, stream: Any = None) -> None:
    """Write ``line`` and its newline in one call, flushed.

    Whole lines, even when sweep workers write to the same terminal or log (``print`` writes the
    newline separately, so another process's line can land between).
    """
    stream = sys.stderr if stream is None else stream
    stream.write(line + "\n")
    stream.flush()


def fail(message: str) -> NoReturn:
    """``amex-run: error: <message>`` on stderr, exit code 2."""
    say(f"{PROG}: error: {message}")
    raise SystemExit(2)


def closing_line(error: BaseException) -> tuple[str, int]:
    """The last line of a stopped or failed run, and its exit code."""
    from amex.app.processes import count_rows, signal_code

    directory = OUTPUT.get("dir")
    kept = f"{count_rows(directory)} episodes kept in {directory}" if directory else ""
    if isinstance(error, OSError):  # e.g. Hydra writing .hydra/ on a full disk
        what = f"cannot write {error.filename}" if error.filename else "a write failed"
        error = JobFailed(AmexError(f"{what}: {error.strerror or error}"), True)
    elif isinstance(error, AmexError):
        error = JobFailed(error)
    elif isinstance(error, Exception):  # anything else Hydra or a job raised
        first = (str(error).strip().splitlines() or [""])[0]
        error = JobFailed(f"{type(error).__name__}: {first} (AMEX_DEBUG=1 shows the traceback)")
    if isinstance(error, JobFailed):
        if not error.resumable:
            return f"{PROG}: error: {error.message}", 2
        tail = f"; {kept}; fix the cause and run the same command to resume" if kept else ""
        return f"{PROG}: error: {error.message}{tail}", 2
    name = str(error) or "SIGINT"
    tail = f": {kept}; the same command resumes" if kept else ": nothing written yet"
    return f"{PROG}: stopped by {name}{tail}", signal_code(error)
