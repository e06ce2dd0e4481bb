"""SIGKILL a sweep midway, re-run it, and get the same results as an uninterrupted sweep."""

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from amex.sim.metrics import TIMING_COLUMNS

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")
ARGS = ["-m", "task=1,3", "method=amex,dmp", "episodes=6", "max_time=6"]


def _rows(sweep: Path):
    out = {}
    for path in sorted(sweep.glob("*/episodes.csv")):
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                key = (row["task"], row["method"], row["env"])
                out[key] = {k: v for k, v in row.items() if k not in TIMING_COLUMNS}
    return out


@pytest.mark.slow
def test_killed_sweep_resumes_to_the_uninterrupted_result(tmp_path):
    env = dict(os.environ)
    full = tmp_path / "full"
    subprocess.run(
        [AMEX_RUN, *ARGS, f"hydra.sweep.dir={full}"],
        check=True,
        env=env,
        capture_output=True,
        timeout=900,
    )
    killed = tmp_path / "killed"
    proc = subprocess.Popen(
        [AMEX_RUN, *ARGS, f"hydra.sweep.dir={killed}"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.time() + 300
    while time.time() < deadline and len(_rows(killed)) < 5:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the launcher and every joblib worker
    proc.wait()
    partial = len(_rows(killed))
    assert 0 < partial < 24
    subprocess.run(
        [AMEX_RUN, *ARGS, f"hydra.sweep.dir={killed}"],
        check=True,
        env=env,
        capture_output=True,
        timeout=900,
    )
    assert _rows(killed) == _rows(full)
