"""Sharded runs: a split cell gives the same rows; the table merges them or says why not."""

import csv
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import fake_slurm
import pytest

from amex.app.sweeps import estimate, order_jobs, sweep_jobs
from amex.core.errors import ConfigError, ShardError
from amex.experiment.shards import ShardSpec, check_cover, shard_envs
from amex.sim.metrics import TIMING_COLUMNS

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")
CELL = ["task=1", "method=dmp", "episodes=7", "max_time=1"]


def _run(args, cwd):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    return subprocess.run(
        [AMEX_RUN, *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=600
    )


def _rows(paths):
    rows = []
    for path in paths:
        with open(path, newline="") as f:
            rows += [
                {k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in csv.DictReader(f)
            ]
    return sorted(rows, key=lambda r: int(r["env"]))


def test_shards_split_the_environments_strided_each_exactly_once():
    for episodes, shards in ((150, 7), (7, 7), (10, 3), (1, 1)):
        parts = [list(shard_envs(episodes, shards, i)) for i in range(shards)]
        assert sorted(sum(parts, [])) == list(range(episodes))
        assert max(map(len, parts)) - min(map(len, parts)) <= 1
    assert list(ShardSpec(2, 7, 150).envs)[:3] == [2, 9, 16]


@pytest.mark.parametrize(
    ("shard", "shards", "episodes", "needle"),
    [
        (7, 7, 150, "shard=7"),
        (-1, 2, 10, "shard=-1"),
        (0, 0, 10, "shards=0"),
        (0, 11, 10, "shards=11"),
    ],
)
def test_a_split_that_leaves_a_shard_empty_or_out_of_range_is_refused(
    shard, shards, episodes, needle
):
    with pytest.raises(ConfigError, match=needle):
        ShardSpec(shard, shards, episodes)


def test_a_multirun_with_shards_runs_every_shard_once_and_the_longest_first():
    jobs = sweep_jobs({}, None, ["task=1,3", "method=cr", "shards=3"])
    assert len(jobs) == 6 and {tuple(j[-1:]) for j in jobs} == {
        ("shard=0",),
        ("shard=1",),
        ("shard=2",),
    }
    assert sweep_jobs({}, None, ["task=1", "shards=3", "shard=1"]) == [
        ["task=1", "shards=3", "shard=1"]
    ]
    ordered = order_jobs(jobs, {"episodes": 150})
    assert all(job[0] == "task=3" for job in ordered[:3])  # CR on Task 3 is the longest cell
    assert estimate(["task=3", "method=cr", "episodes=150"], {}) > estimate(
        ["task=3", "method=cr", "episodes=150", "outer_hz=20"], {}
    )


def test_grids_run_the_union_of_their_products_each_job_once():
    grids = {
        "speed": {
            "method": "amex,dmp",
            "scenario.goal_speed_std": "0.1,0.2",
            "perception.noise_std": "0.005",
        },
        "noise": {
            "method": "amex,dmp",
            "scenario.goal_speed_std": "0.1",
            "perception.noise_std": "0,0.005",
        },
    }
    jobs = sweep_jobs({"task": "2"}, grids, ["episodes=5"])
    assert len(jobs) == 6  # 4 + 4, the shared (0.1, 5 mm) cells once
    assert all("task=2" in job and "episodes=5" in job for job in jobs)
    narrowed = sweep_jobs({"task": "2"}, grids, ["method=amex"])  # the command line wins
    assert len(narrowed) == 3 and all("method=amex" in job for job in narrowed)


def test_shards_that_overlap_or_leave_gaps_are_refused_naming_them():
    envs = {i: set(shard_envs(10, 3, i)) for i in range(3)}
    full = {f"d{i}": (ShardSpec(i, 3, 10), envs[i]) for i in range(3)}
    check_cover("task 1 dmp", full)
    with pytest.raises(
        ShardError, match=r"environments 1, 4, 7 of 10 are missing \(shard 1 of 3 \(no run\)\)"
    ):
        check_cover("task 1 dmp", {k: v for k, v in full.items() if k != "d1"})
    with pytest.raises(ShardError, match=r"environment 0 is in two shards \(d0 and e\)"):
        check_cover("task 1 dmp", {**full, "e": (ShardSpec(0, 3, 10), {0})})
    with pytest.raises(ShardError, match="shards of different splits"):
        check_cover("task 1 dmp", {**full, "e": (ShardSpec(0, 5, 10), {0, 5})})
    with pytest.raises(ShardError, match="sharded and unsharded"):
        check_cover("task 1 dmp", {**full, "plain": (None, set(range(10)))})
    check_cover("task 1 dmp", {"a": (None, {0, 1}), "b": (None, {0, 1})})  # reruns: as before


@pytest.mark.slow
def test_sharded_cell_gives_the_unsharded_rows_and_table_and_refuses_a_missing_shard(tmp_path):
    from analysis.table import main as table

    whole, split = tmp_path / "whole", tmp_path / "split"
    proc = _run(["-m", *CELL, f"hydra.sweep.dir={whole}"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    proc = _run(["-m", *CELL, "shards=3", f"hydra.sweep.dir={split}"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "3 jobs in" in proc.stderr.splitlines()[-1] and "CPU" in proc.stderr.splitlines()[-1]
    shards = sorted(split.glob("*/episodes.csv"))
    assert [p.parent.name for p in shards] == [f"task1_dmp_seed0_shard{i}of3" for i in range(3)]
    assert _rows(shards) == _rows(whole.glob("*/episodes.csv"))
    for runs, out in ((whole, tmp_path / "t_whole"), (split, tmp_path / "t_split")):
        assert table([str(runs), "--out", str(out)]) == 0
    header = (tmp_path / "t_whole" / "fig5.csv").read_text().splitlines()[0].split(",")
    keep = [c for c in header if "compute" not in c]

    def fig5(out):
        with open(out / "fig5.csv", newline="") as f:
            return [{k: r[k] for k in keep} for r in csv.DictReader(f)]

    assert fig5(tmp_path / "t_split") == fig5(tmp_path / "t_whole")
    shutil.rmtree(split / "task1_dmp_seed0_shard1of3")
    assert table([str(split), "--out", str(tmp_path / "t_gap")]) == 2
    # and the same command runs only the missing shard again
    proc = _run(["-m", *CELL, "shards=3", f"hydra.sweep.dir={split}"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert _rows(sorted(split.glob("*/episodes.csv"))) == _rows(whole.glob("*/episodes.csv"))


def test_a_shard_out_of_range_or_a_subdir_without_the_shard_is_one_line(tmp_path):
    proc = _run([*CELL, "shards=3", "shard=3", f"hydra.run.dir={tmp_path / 'r'}"], tmp_path)
    assert proc.returncode == 2 and "shard=3" in proc.stderr and len(proc.stderr.splitlines()) == 1
    proc = _run(
        ["-m", *CELL, "shards=2", "hydra.sweep.subdir=same", f"hydra.sweep.dir={tmp_path / 's'}"],
        tmp_path,
    )
    assert proc.returncode == 2 and "two jobs of the sweep write into" in proc.stderr, proc.stderr
    assert not (tmp_path / "s").exists()


@pytest.mark.slow
def test_a_sharded_sweep_on_submitit_local_writes_every_shard_and_tabulates(tmp_path):
    from analysis.table import main as table

    sweep = tmp_path / "sweep"
    args = ["-m", "hydra/launcher=submitit_local", *CELL, "shards=2", f"hydra.sweep.dir={sweep}"]
    proc = _run(args, tmp_path)
    assert proc.returncode == 0, proc.stderr
    shards = sorted(sweep.glob("*/episodes.csv"))
    assert [p.parent.name for p in shards] == [
        "task1_dmp_seed0_shard0of2",
        "task1_dmp_seed0_shard1of2",
    ]
    assert [int(r["env"]) for r in _rows(shards)] == list(range(7))
    assert table([str(sweep), "--out", str(tmp_path / "table")]) == 0
    assert "| 1 | dmp | 7 |" in (tmp_path / "table" / "fig5.md").read_text()


@pytest.fixture
def slurm(tmp_path, monkeypatch):
    """The local stand-in for SLURM (``tests/fake_slurm.py``): its state dir and environment."""
    state = tmp_path / "slurm"
    env = fake_slurm.install(tmp_path / "bin", state)
    env.pop("AMEX_DEBUG", None)
    monkeypatch.setenv("FAKE_SLURM_DIR", str(state))
    yield state, env
    fake_slurm.shutdown(state)


@pytest.mark.slow
def test_a_sharded_sweep_on_the_slurm_launcher_is_one_job_array(tmp_path, slurm):
    """The shipped SLURM config through submitit, scheduled by a local stand-in for SLURM."""
    from analysis.table import main as table

    state, env = slurm
    sweep = tmp_path / "sweep"
    args = [
        "-m",
        "hydra/launcher=slurm",
        "hydra.launcher.partition=cpu",
        "task=1",
        "method=dmp,amex",
        "episodes=7",
        "max_time=1",
        "shards=3",
        f"hydra.sweep.dir={sweep}",
    ]
    proc = subprocess.run(
        [AMEX_RUN, *args], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600
    )
    assert proc.returncode == 0, proc.stderr
    (job,) = fake_slurm.submissions(state)  # one sbatch call for the whole sweep
    flags = job["flags"]
    assert flags["array"] == "0-5%6", flags
    assert flags["cpus-per-task"] == "1" and flags["partition"] == "cpu", flags
    assert "export OMP_NUM_THREADS=1" in job["script"]
    dirs = sorted(p.parent.name for p in sweep.glob("*/episodes.csv"))
    assert dirs == [f"task1_{m}_seed0_shard{i}of3" for m in ("amex", "dmp") for i in range(3)]
    for method in ("amex", "dmp"):
        rows = _rows(sorted(sweep.glob(f"task1_{method}_*/episodes.csv")))
        assert [int(r["env"]) for r in rows] == list(range(7))
    assert table([str(sweep), "--out", str(tmp_path / "table")]) == 0
    assert "| 1 | dmp | 7 |" in (tmp_path / "table" / "fig5.md").read_text()
    closing = proc.stderr.strip().splitlines()[-1]
    assert closing.startswith(f"sweep {sweep}: 6 jobs in "), closing
    assert "CPU in the jobs' runs (elsewhere" in closing and "longest job" in closing, closing


@pytest.mark.slow
def test_a_preempted_slurm_task_is_requeued_and_resumes(tmp_path, slurm):
    """SLURM's warning signal (USR2) makes submitit requeue the task; the rerun keeps the rows."""
    state, env = slurm
    sweep = tmp_path / "sweep"
    cell = sweep / "task3_cr_seed0"
    args = ["-m", "hydra/launcher=slurm", "task=3", "method=cr", "episodes=8"]
    proc = subprocess.Popen(
        [AMEX_RUN, *args, f"hydra.sweep.dir={sweep}"],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while len(_rows([cell / "episodes.csv"]) if (cell / "episodes.csv").exists() else []) < 2:
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.05)
        (step,) = fake_slurm.steps(state).values()
        os.kill(step, signal.SIGUSR2)  # what sbatch --signal=USR2@90 sends before a limit
        out, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    (task,) = {p.stem for p in state.glob("*.state")}
    assert fake_slurm.attempts(state, task) == 2
    log = (sweep / ".submitit" / task / f"{task}_0_log.err").read_text()
    assert "this job is preempted" in log, log
    assert "Traceback" not in log and "amex-run: stopped by SIGTERM: " in log, log
    starts = [int(n) for n in re.findall(r"(\d+) recorded earlier", (cell / "run.log").read_text())]
    assert len(starts) == 2 and starts[0] == 0 and 2 <= starts[1] < 8, starts  # resumed
    assert [int(r["env"]) for r in _rows([cell / "episodes.csv"])] == list(range(8))
