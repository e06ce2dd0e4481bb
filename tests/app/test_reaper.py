"""The sweep's reaper (amex/app/reaper.py) with real processes: a launcher killed by SIGKILL.

The "half-started worker" here is a process that ignores SIGTERM and sleeps, as loky's blocked
processes do in effect: nothing of amex runs in it, so only the reaper can end it.
"""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from amex.app.reaper import MARK, alive, marked

pytestmark = pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs /proc")

LAUNCHER = textwrap.dedent(
    """
    import os, subprocess, sys, time
    from amex.app.reaper import MARK, start_reaper
    os.environ[MARK] = str(os.getpid())
    reaper = start_reaper(grace=float(sys.argv[1]))
    assert start_reaper() is None  # once per process
    stuck = subprocess.Popen([sys.executable, "-c",
        "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(300)"])
    print(reaper, stuck.pid, flush=True)
    if sys.argv[2] == "wait":
        time.sleep(300)
    """
)


def _wait_gone(pids, timeout: float) -> float:
    start = time.monotonic()
    while any(alive(p) for p in pids) and time.monotonic() - start < timeout:
        time.sleep(0.1)
    return time.monotonic() - start


def _launch(grace: float, mode: str):
    proc = subprocess.Popen([sys.executable, "-c", LAUNCHER, str(grace), mode],
                            stdout=subprocess.PIPE, text=True)  # fmt: skip
    reaper, stuck = map(int, proc.stdout.readline().split())
    return proc, reaper, stuck


def test_a_launcher_killed_by_sigkill_leaves_nothing_after_the_grace():
    proc, reaper, stuck = _launch(1.0, "wait")
    try:
        assert alive(reaper) and alive(stuck)
        deadline = time.monotonic() + 5  # a child's environment can read empty just after exec
        while not marked(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert marked(proc.pid) == [stuck]  # the reaper itself carries no mark
        assert f"{MARK}={proc.pid}".encode() not in Path(f"/proc/{reaper}/environ").read_bytes()
        time.sleep(1.5)
        assert alive(stuck)  # the reaper waits while the launcher lives
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        waited = _wait_gone([stuck, reaper], 20)
        assert not alive(stuck) and not alive(reaper)
        assert 1.0 <= waited < 10  # the grace first, then SIGKILL
    finally:
        for pid in (stuck, reaper):
            if alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_a_launcher_that_ends_leaves_a_reaper_that_ends_with_what_it_left():
    proc, reaper, stuck = _launch(1.0, "exit")
    proc.wait()
    assert proc.returncode == 0
    _wait_gone([stuck, reaper], 20)
    assert not alive(stuck) and not alive(reaper)


def test_ctrl_c_to_the_launchers_group_does_not_reach_the_reaper():
    proc, reaper, stuck = _launch(0.5, "wait")
    try:
        assert os.getsid(reaper) == reaper != os.getsid(proc.pid)  # a session of its own
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        _wait_gone([stuck, reaper], 20)
    assert not alive(stuck) and not alive(reaper)
