"""Stopping cleanly: signals as exceptions, and sweep workers that never outlive their sweep.

* :class:`Interrupted`: SIGINT or SIGTERM turned into an exception (a :class:`KeyboardInterrupt`,
  so joblib aborts a sweep's remaining jobs and kills its workers on the way out), raised in the
  main thread between two Python bytecodes: ``finally`` blocks run, the open episode log is
  finished, the run directory's lock is released, and the rows written stay. A stop raised while
  a compiled function (numba's dispatcher, a C extension) was returning reaches Python as a
  ``SystemError`` ("returned a result with an exception set") caused by it; :func:`signals_raise`
  re-raises the stop itself (:func:`stop_behind`), ours or submitit's ``SystemExit`` alike.
* :func:`watch_parent`: a sweep worker (a joblib/loky process, a submitit local job) whose
  launching process dies, even by SIGKILL, notices within half a second that it was re-parented
  and stops itself with SIGTERM (forcibly after ``grace`` seconds); what no amex code runs in
  yet (a worker loky is still spawning) is ended by the sweep's reaper (:mod:`amex.app.reaper`).
* :func:`count_rows`: how many episodes a run or sweep directory holds, for the closing line.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from types import FrameType

from amex.app.reaper import MARK
from amex.core.errors import Interrupted, stop_behind

#: Environment variable holding the pid of the process that launched a sweep.
LAUNCHER_PID = MARK
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _raise_interrupted(signum: int, frame: FrameType | None) -> None:
    raise Interrupted(signum)


@contextlib.contextmanager
def signals_raise(signums: tuple[int, ...] = STOP_SIGNALS) -> Iterator[None]:
    """Within the block, ``signums`` raise :class:`Interrupted` (main thread only).

    A ``SystemError`` raised from a stop is re-raised as that stop (:func:`stop_behind`).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _raise_interrupted) for s in signums}
    try:
        yield
    except SystemError as error:
        stop = stop_behind(error)
        if stop is None:
            raise
        raise stop from None
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def signal_code(error: BaseException) -> int:
    """The conventional exit code of a stop: 128 + the signal number (130 for Ctrl-C)."""
    return 128 + int(getattr(error, "signum", signal.SIGINT))


class ParentWatch:
    """The watch of :func:`watch_parent`: ``orphaned`` is set once the parent is gone."""

    def __init__(self) -> None:
        self.orphaned = threading.Event()
        self._stop = threading.Event()

    def stop(self) -> None:
        """End the watch (the job finished while its parent lived)."""
        self._stop.set()


def _ancestors() -> list[int]:
    """The ancestors of this process, nearest first (from ``/proc``; without it: the parent)."""
    chain, pid = [], os.getpid()
    for _ in range(64):
        fields = _proc_stat(pid)
        if fields is None:
            break
        pid = int(fields[1])
        if pid <= 1:
            break
        chain.append(pid)
    return chain or [os.getppid()]


def watch_parent(
    parent: int, period: float = 0.5, grace: float = 10.0, local: bool = True
) -> ParentWatch | None:
    """Stop this process when ``parent``, the process that launched its sweep, exits.

    A daemon thread polls whether ``parent`` is still an ancestor of this process (a joblib
    worker is its child; a submitit-local job its grandchild); once it is not (it died, however),
    the thread sends SIGTERM to its own process (:class:`Interrupted` in the main thread, if
    :func:`signals_raise` is active) and, should the process still live ``grace`` seconds later,
    ends it with ``os._exit(143)``. A ``local`` job whose launcher is already gone when it starts
    (killed while handing out jobs) gets a watch that is already ``orphaned``: the caller must
    not run the job. Returns None (and watches nothing) for a job that is not ``local``, e.g. a
    SLURM job, whose launcher is on another machine.
    """
    if not local:
        return None
    watch = ParentWatch()
    if parent not in _ancestors():
        watch.orphaned.set()
        return watch
    direct = os.getppid() == parent

    def alive() -> bool:
        return os.getppid() == parent if direct else parent in _ancestors()

    def poll() -> None:
        while alive():
            if watch._stop.wait(period):
                return
        watch.orphaned.set()
        os.kill(os.getpid(), signal.SIGTERM)
        threading.Event().wait(grace)
        os._exit(128 + signal.SIGTERM)

    threading.Thread(target=poll, name="amex-parent-watch", daemon=True).start()
    return watch


def count_rows(directory: Path | None) -> int:
    """Episodes recorded in every ``episodes.csv`` at or below ``directory`` (0 if none)."""
    if directory is None or not directory.is_dir():
        return 0
    total = 0
    for path in [directory / "episodes.csv", *directory.glob("*/episodes.csv")]:
        with contextlib.suppress(OSError):
            total += max(path.read_bytes().count(b"\n") - 1, 0)
    return total


def _proc_stat(pid: int | str) -> list[str] | None:
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text.rsplit(")", 1)[1].split()  # fields from 3 (state) on; the name may hold spaces


def tree_cpu_time() -> float:
    """CPU time [s] of this process and every process it started, finished or still running.

    This process and its waited-for children from ``getrusage``; the children and grandchildren
    still running (a sweep's joblib workers) from ``/proc/<pid>/stat`` (user + system time, and
    that of their own waited-for children). Without ``/proc``, the first part only.
    """
    import resource

    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        usage = resource.getrusage(who)
        total += usage.ru_utime + usage.ru_stime
    proc = Path("/proc")
    if not proc.is_dir():
        return total
    stats = {}
    for entry in proc.iterdir():
        if entry.name.isdigit():
            fields = _proc_stat(entry.name)
            if fields is not None:
                stats[int(entry.name)] = fields
    tick = os.sysconf("SC_CLK_TCK")
    frontier, seen = {os.getpid()}, set()
    while frontier:
        children = {p for p, f in stats.items() if int(f[1]) in frontier and p not in seen}
        seen |= children
        frontier = children
    for pid in seen:  # fields 14-17: utime, stime, cutime, cstime (here at indices 11-14)
        total += sum(int(x) for x in stats[pid][11:15]) / tick
    return total
