"""A sweep's reaper: a small process that outlives a killed launcher and ends what it left behind.

A local sweep's workers stop themselves when their launcher dies (:func:`amex.app.processes.
watch_parent`), but only once amex code runs in them. While joblib's loky backend spawns them,
a SIGKILL to the launcher can leave a half-started worker and loky's resource trackers blocked
on each other's pipes before any of our code runs there. The reaper covers that window and any
other: the launcher starts it (:func:`start_reaper`) before it hands out a job, in a session of
its own and without the launcher's mark in its environment, and it waits.

* While its parent, the launcher, lives, it sleeps (a ``getppid()`` every 0.2 s).
* Once the launcher is gone, it gives every process marked with the launcher's pid
  (``AMEX_LAUNCHER_PID=<pid>`` in ``/proc/<pid>/environ``) ``grace`` seconds to end by itself
  (a worker running a job finishes its log and stops on its own watch within 10 s), then kills
  those still there with SIGKILL, and exits. They hold no lock (the kernel releases ``flock``)
  and anything they wrote is complete (rows) or recoverable (logs).

This file runs as a script (``python -I -S reaper.py <launcher pid> <grace>``): the standard
library only, so it starts in ~10 ms and cannot block on what it watches.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

MARK = "AMEX_LAUNCHER_PID"  # the environment variable naming a sweep's launcher
GRACE = 15.0  # [s] after the launcher's death, before what is left is killed
POLL = 0.2  # [s]


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (exists and is no zombie)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def marked(launcher: int) -> list[int]:
    """The processes whose environment marks ``launcher`` as their sweep's launcher."""
    mark = f"{MARK}={launcher}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                if mark in (entry / "environ").read_bytes().split(b"\0"):
                    found.append(int(entry.name))
            except OSError:  # gone, or not ours to read
                continue
    return found


def reap(launcher: int, grace: float = GRACE) -> list[int]:
    """Wait for ``launcher`` (this process's parent) to end, then for its marked processes.

    Those left after ``grace`` seconds are killed; returns their pids.
    """
    while os.getppid() == launcher:
        time.sleep(POLL)
    deadline = time.monotonic() + grace
    while time.monotonic() < deadline:
        if not marked(launcher):
            return []
        time.sleep(POLL)
    killed = []
    for pid in marked(launcher):
        try:
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
        except OSError:
            continue
    return killed


_started: set[int] = set()  # the pids (this process, forks) that started their reaper


def start_reaper(grace: float = GRACE) -> int | None:
    """Start the reaper of this process's sweeps, once per process (module notes).

    Returns its pid, or None where there is no ``/proc`` or it runs already.
    """
    if os.getpid() in _started or not Path("/proc/self/environ").exists():
        return None
    env = {k: v for k, v in os.environ.items() if k != MARK}
    null = os.devnull
    pid = os.posix_spawn(
        sys.executable,
        [sys.executable, "-I", "-S", __file__, str(os.getpid()), repr(float(grace))],
        env,
        file_actions=[(os.POSIX_SPAWN_OPEN, fd, null, os.O_RDWR, 0) for fd in (0, 1, 2)],
        setsid=True,  # a session of its own: a terminal's Ctrl-C to the sweep does not reach it
    )
    _started.add(os.getpid())
    return pid


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    reap(int(sys.argv[1]), float(sys.argv[2]) if len(sys.argv) > 2 else GRACE)
