"""A one-machine stand-in for SLURM's commands, to test what amex hands to a cluster.

``install(bin_dir, state_dir)`` writes ``sbatch``, ``srun``, ``sacct``, ``scancel`` and ``scontrol``
into ``bin_dir``. They implement the part of SLURM that submitit uses, on this machine:

* ``sbatch SCRIPT`` records the submission (``state_dir/submissions.jsonl``: the script and its
  ``#SBATCH`` flags), answers ``Submitted batch job N`` and runs the job's array tasks in a detached
  process, at most two at a time, each as ``bash SCRIPT`` with the environment SLURM gives an array
  task (``SLURM_ARRAY_JOB_ID``, ``SLURM_ARRAY_TASK_ID``, ...);
* ``srun --output F [--error G] CMD`` runs CMD with its streams appended to F and G (``%A``, ``%a``,
  ``%j``, ``%t`` expanded as SLURM does);
* ``sacct -j N ...`` reports each array task as PENDING, RUNNING, COMPLETED or FAILED;
* ``scancel`` stops a task (SIGTERM to all its processes) and marks it CANCELLED; ``scontrol
  requeue`` stops it the same way and runs it again, as SLURM does with a preempted task.

``steps(state_dir)`` gives the pid of each running task's step (what srun started), the process
SLURM's ``--signal`` reaches.

The scheduler is the only thing replaced: the submitted script, submitit's job files and the jobs
themselves are the real ones.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

COMMANDS = ("sbatch", "srun", "sacct", "scancel", "scontrol")
PARALLEL = 2


def install(bin_dir: Path, state_dir: Path) -> dict[str, str]:
    """Write the commands into ``bin_dir``; return an environment with them first on PATH."""
    bin_dir.mkdir(parents=True, exist_ok=True)
    state_dir.mkdir(parents=True, exist_ok=True)
    here = Path(__file__).resolve().parent
    for name in COMMANDS:
        path = bin_dir / name
        path.write_text(
            f"#!{sys.executable}\n"
            "import sys\n"
            f"sys.path.insert(0, {str(here)!r})\n"
            "from fake_slurm import main\n"
            f"sys.exit(main({name!r}, sys.argv[1:]))\n"
        )
        path.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["FAKE_SLURM_DIR"] = str(state_dir)
    return env


def submissions(state_dir: Path) -> list[dict]:
    """Every ``sbatch`` call so far: ``{"job": N, "flags": {...}, "script": text}``."""
    path = state_dir / "submissions.jsonl"
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines()]


def steps(state_dir: Path) -> dict[str, int]:
    """``{task: pid}`` of the steps running now (srun's command); tasks as in :func:`attempts`."""
    return {p.stem: int(p.read_text()) for p in state_dir.glob("*.step") if p.read_text()}


def attempts(state_dir: Path, task: str) -> int:
    """How many times the task ``"<job>"`` or array task ``"<job>_<index>"`` was started."""
    path = state_dir / f"{task}.attempts"
    return int(path.read_text()) if path.exists() else 0


def shutdown(state_dir: Path) -> None:
    """Stop every task still running (a test's clean-up, whatever it asserted)."""
    os.environ["FAKE_SLURM_DIR"] = str(state_dir)
    _cancel(sorted({p.stem.split("_")[0] for p in state_dir.glob("*.state")}))


def _state() -> Path:
    return Path(os.environ["FAKE_SLURM_DIR"])


def _set(task: str, state: str) -> None:
    (_state() / f"{task}.state").write_text(state)


def _flags(script: str) -> dict[str, str]:
    flags = {}
    for m in re.finditer(r"^#SBATCH --([\w-]+)(?:=(.*))?$", script, re.M):
        flags[m.group(1)] = m.group(2) if m.group(2) is not None else ""
    return flags


def _sbatch(args: list[str]) -> int:
    script_path = Path(args[-1])
    script = script_path.read_text()
    flags = _flags(script)
    counter = _state() / "next_job"
    job = int(counter.read_text()) if counter.exists() else 1000
    counter.write_text(str(job + 1))
    if "array" in flags:
        m = re.fullmatch(r"0-(\d+)(?:%\d+)?", flags["array"])
        assert m, f"unsupported --array={flags['array']}"
        tasks = [f"{job}_{i}" for i in range(int(m.group(1)) + 1)]
    else:
        tasks = [str(job)]
    with open(_state() / "submissions.jsonl", "a") as f:
        f.write(json.dumps({"job": job, "flags": flags, "script": script}) + "\n")
    for task in tasks:
        _set(task, "PENDING")
    subprocess.Popen(
        [sys.executable, __file__, "_run", str(script_path.resolve()), *tasks],
        start_new_session=True,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=dict(os.environ),
    )
    print(f"Submitted batch job {job}")
    return 0


def _run_array(script: str, tasks: list[str]) -> None:
    def one(task: str) -> None:
        env = dict(os.environ)
        job, _, index = task.partition("_")
        env.update(
            SLURM_NTASKS="1",
            SLURM_JOB_NUM_NODES="1",
            SLURM_NODEID="0",
            SLURM_PROCID="0",
            SLURM_LOCALID="0",
            SLURM_JOB_NODELIST="localhost",
        )
        if index:  # an array task: its own job id, and the array's
            env.update(
                SLURM_JOB_ID=str(int(job) * 1000 + int(index) + 1),
                SLURM_ARRAY_JOB_ID=job,
                SLURM_ARRAY_TASK_ID=index,
            )
        else:
            env["SLURM_JOB_ID"] = job
        state = _state() / f"{task}.state"
        while state.read_text() in ("PENDING", "REQUEUED"):
            count = _state() / f"{task}.attempts"
            count.write_text(str(attempts(_state(), task) + 1))
            proc = subprocess.Popen(["bash", script], env=env, start_new_session=True)
            (_state() / f"{task}.pid").write_text(str(proc.pid))
            _set(task, "RUNNING")
            code = proc.wait()
            _wait_for_group(proc.pid)  # SLURM reruns a task once all its processes are gone
            if state.read_text() == "RUNNING":
                _set(task, "COMPLETED" if code == 0 else "FAILED")

    with ThreadPoolExecutor(PARALLEL) as pool:
        list(pool.map(one, tasks))


def _alive_in_group(group: int) -> bool:
    """Whether a process of process group ``group`` is still running (zombies aside)."""
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, ValueError, IndexError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[2]) == group and fields[0] != "Z":  # state, ppid, pgrp
                return True
    return False


def _wait_for_group(group: int, timeout: float = 120.0) -> None:
    """Wait until every process of the task's session has ended (at most ``timeout`` s).

    A task's script is its session's leader: it can end before the job it started has finished
    handling SLURM's SIGTERM (amex-run closes its records on it). SLURM requeues a task only
    once all of its processes have ended, and so does this stand-in.
    """
    deadline = time.monotonic() + timeout
    while _alive_in_group(group) and time.monotonic() < deadline:
        time.sleep(0.02)


def _task_id() -> str:
    env = os.environ
    if "SLURM_ARRAY_JOB_ID" in env:
        return f"{env['SLURM_ARRAY_JOB_ID']}_{env['SLURM_ARRAY_TASK_ID']}"
    return env["SLURM_JOB_ID"]


def _srun(args: list[str]) -> int:
    streams = {"--output": None, "--error": None}
    i = 0
    while i < len(args) and args[i].startswith("--"):
        if args[i] in streams:
            streams[args[i]] = args[i + 1]
            i += 2
        else:
            i += 1
    env = os.environ

    def expand(path: str | None) -> str | None:
        if path is None:
            return None
        for key, value in (
            ("%A", env.get("SLURM_ARRAY_JOB_ID", "")),
            ("%a", env.get("SLURM_ARRAY_TASK_ID", "")),
            ("%j", env.get("SLURM_JOB_ID", "")),
            ("%t", "0"),
        ):
            path = path.replace(key, value)
        return path

    out, err = expand(streams["--output"]), expand(streams["--error"])
    step = _state() / f"{_task_id()}.step"
    with contextlib.ExitStack() as files:
        stdout = files.enter_context(open(out, "a")) if out else None
        stderr = files.enter_context(open(err, "a")) if err else None
        proc = subprocess.Popen(args[i:], stdout=stdout, stderr=stderr or stdout)
        step.write_text(str(proc.pid))
        code = proc.wait()
    step.write_text("")
    return code


def _sacct(args: list[str]) -> int:
    jobs = [args[i + 1] for i, a in enumerate(args) if a == "-j"]
    print("JobID|State|NodeList")
    for job in jobs:
        main_id = job.split("_")[0]
        found = [*_state().glob(f"{main_id}.state"), *_state().glob(f"{main_id}_*.state")]
        for path in sorted(found):
            print(f"{path.stem}|{path.read_text()}|localhost")
    return 0


def _cancel(ids: list[str], state: str = "CANCELLED") -> int:
    for job in ids:
        main_id = job.split("_")[0]
        for path in [*_state().glob(f"{main_id}.state"), *_state().glob(f"{main_id}_*.state")]:
            if "_" in job and path.stem != job:
                continue
            path.write_text(state)
            pid = path.with_suffix(".pid")
            if pid.exists():
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(int(pid.read_text()), signal.SIGTERM)
    return 0


def main(name: str, args: list[str]) -> int:
    if name == "sbatch":
        return _sbatch(args)
    if name == "srun":
        return _srun(args)
    if name == "sacct":
        return _sacct(args)
    if name == "scancel":
        return _cancel([a for a in args if not a.startswith("-")])
    if name == "scontrol":
        return _cancel(args[1:], "REQUEUED") if args[:1] == ["requeue"] else 0
    raise SystemExit(f"fake_slurm: unknown command {name}")


if __name__ == "__main__" and sys.argv[1:2] == ["_run"]:
    _run_array(sys.argv[2], sys.argv[3:])
