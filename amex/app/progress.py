"""What a ``-m`` sweep shows while it runs and says when it ends (a Hydra callback).

While it runs: one progress bar for the whole sweep, in the launching process. Jobs run in worker
processes (joblib), in subprocesses (submitit) or on other machines (SLURM), so the bar only
counts the rows that appear in the sweep's ``*/episodes.csv`` files, every half second, against
the environments of every job (:func:`amex.app.sweeps.sweep_jobs`, shards counted as theirs).

At its end, one line: the command's wall time and total CPU time (its checks before the launch
included) and the sweep's longest job, e.g.
``sweep runs/paper: 12 jobs in 6 min 2 s wall, 11 min 50 s CPU (1.96 cores busy on average),
longest job 2 min 1 s (task3_cr_seed0)``. The CPU time is that of this process and every process
it started (:func:`amex.app.processes.tree_cpu_time`: the workers, reaped or alive), or, when the
jobs
ran elsewhere (SLURM), the sum of the jobs' own CPU times from their ``summary.json``, said as
such (their start-up is not in it); the
longest job is the longest run of this sweep by its ``summary.json``
(:mod:`amex.experiment.runner`).
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

from hydra.experimental.callback import Callback
from omegaconf import OmegaConf

from amex.app.session import say

#: The sweeps of this process (to stop their bars before a closing line).
SWEEPS: list[SweepProgress] = []


class SweepCost(NamedTuple):
    """What a sweep cost.

    Attributes:
        jobs: jobs that finished during the sweep.
        wall: wall time of the sweep [s].
        cpu: CPU time of the sweep [s] (module notes).
        longest: wall time of its longest job [s] (nan without jobs).
        longest_name: that job's directory name.
        elsewhere: the jobs ran outside this process tree (SLURM): ``cpu`` is the sum of their
            runs' own CPU times, without their start-up.
    """

    jobs: int
    wall: float
    cpu: float
    longest: float
    longest_name: str
    elsewhere: bool = False


def duration(seconds: float) -> str:
    """``6 min 2 s``, ``1 h 3 min``, ``42.0 s``."""
    if not math.isfinite(seconds):
        return "-"
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes, sec = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {sec} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes} min"


def summary_stamps(sweep_dir: Path) -> dict[str, tuple[int, int, int]]:
    """``(inode, size, mtime_ns)`` of every job's ``summary.json`` in ``sweep_dir``, by job name."""
    stamps = {}
    for path in sweep_dir.glob("*/summary.json"):
        with contextlib.suppress(OSError):
            info = path.stat()
            stamps[path.parent.name] = (info.st_ino, info.st_size, info.st_mtime_ns)
    return stamps


def job_records(
    sweep_dir: Path, before: dict[str, tuple[int, int, int]]
) -> dict[str, dict[str, Any]]:
    """``summary.json`` of every job written since ``before`` (:func:`summary_stamps`).

    A job counts when its summary is new or was replaced: no wall-clock comparison, so a clock
    step during the sweep changes nothing.
    """
    records = {}
    for name, stamp in sorted(summary_stamps(sweep_dir).items()):
        if before.get(name) != stamp:
            with contextlib.suppress(OSError, ValueError):
                records[name] = json.loads((sweep_dir / name / "summary.json").read_text())
    return records


def sweep_cost(
    sweep_dir: Path,
    before: dict[str, tuple[int, int, int]],
    wall: float,
    local_cpu: float,
    elsewhere: bool = False,
) -> SweepCost:
    """The cost of a sweep whose directory held the summaries ``before`` when it started.

    ``wall``: its wall time; ``local_cpu``: the CPU time of this process tree; ``elsewhere``:
    the jobs ran on other machines (SLURM), so the CPU time is the sum of theirs instead.
    """
    records = job_records(sweep_dir, before)
    walls = {name: float(r.get("wall_time", math.nan)) for name, r in records.items()}
    jobs_cpu = sum(float(r.get("cpu_time", 0.0)) for r in records.values())
    known = {n: w for n, w in walls.items() if math.isfinite(w)}
    name = max(known, key=known.__getitem__) if known else ""
    cpu = jobs_cpu if elsewhere else max(local_cpu, jobs_cpu)
    return SweepCost(len(records), wall, cpu, known.get(name, math.nan), name, elsewhere)


def describe(sweep_dir: Path, cost: SweepCost) -> str:
    """The closing line of a sweep (module notes)."""
    busy = cost.cpu / cost.wall if cost.wall > 0 else math.nan
    longest = f"longest job {duration(cost.longest)} ({cost.longest_name})" if cost.jobs else ""
    if cost.elsewhere:
        cpu = f"{duration(cost.cpu)} CPU in the jobs' runs (elsewhere; their start-up not counted)"
    else:
        cpu = f"{duration(cost.cpu)} CPU ({busy:.2f} cores busy on average)"
    jobs = f"{cost.jobs} job" + ("" if cost.jobs == 1 else "s")
    return f"sweep {sweep_dir}: {jobs} in {duration(cost.wall)} wall, {cpu}" + (
        f", {longest}" if longest else ""
    )


def run_line(summary: dict[str, Any]) -> str:
    """A run's result in one line: success rate, final time, failures (its ``summary.json``)."""
    s = summary["success"]["mean"]
    t = summary["final_time"]
    return (
        f"success {s:.3f}  final time {t['mean']:.2f} +- {t['two_std']:.2f} s  "
        f"({summary['failures']} failures)"
    )


class LineBar:
    """A progress bar for logs (not a terminal): a whole line every ``every`` seconds, and last.

    tqdm redraws its line with carriage returns, which a log file (CI, SLURM) keeps as one line
    with every other line glued onto it. The subset of tqdm's interface that amex uses.
    """

    def __init__(self, total: int, desc: str, every: float = 10.0) -> None:
        self.total, self.desc, self.every = total, desc, every
        self.n = 0
        self._postfix = ""
        self._shown = -1
        self._last = time.monotonic()

    def __enter__(self) -> LineBar:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _line(self) -> str:
        share = f" ({100.0 * self.n / self.total:.0f} %)" if self.total else ""
        tail = f", {self._postfix}" if self._postfix else ""
        return f"{self.desc}: {self.n}/{self.total} episodes{share}{tail}"

    def _show(self, force: bool = False) -> None:
        now = time.monotonic()
        if self.n != self._shown and (force or now - self._last >= self.every):
            say(self._line())
            self._shown, self._last = self.n, now

    def update(self, n: int = 1) -> None:
        """Count ``n`` more episodes."""
        self.n += n
        self._show(force=self.n >= self.total)

    def set_postfix(self, refresh: bool = True, **values: Any) -> None:
        """Text after the count, e.g. ``success=3/4``."""
        self._postfix = ", ".join(f"{k}={v}" for k, v in values.items())

    def write(self, text: str, file: Any = None) -> None:
        """A line of its own."""
        say(text, file or sys.stderr)

    def close(self) -> None:
        """The final count."""
        self._show(force=True)


@contextlib.contextmanager
def console_warnings() -> Iterator[None]:
    """Only warnings of the run's log on the console for the block; the record is ``run.log``.

    On a terminal the console's lines go through tqdm (``logging_redirect_tqdm``), so that they
    do not break its bar; in a log (:class:`LineBar`), the console handlers are only raised to
    ``WARNING`` (tqdm's logging helpers, which import asyncio, ~25 ms, are not loaded).
    """
    import logging

    if sys.stderr.isatty():
        from tqdm.contrib.logging import logging_redirect_tqdm

        with logging_redirect_tqdm():
            for handler in logging.getLogger().handlers:  # tqdm's console handler
                if type(handler).__name__ == "_TqdmLoggingHandler":
                    handler.setLevel(logging.WARNING)
            yield
        return
    console = [
        h
        for h in logging.getLogger().handlers
        if type(h) is logging.StreamHandler and h.stream in (sys.stdout, sys.stderr)
    ]
    levels = [h.level for h in console]
    for handler in console:
        handler.setLevel(max(handler.level, logging.WARNING))
    try:
        yield
    finally:
        for handler, level in zip(console, levels, strict=True):
            handler.setLevel(level)


def progress_bar(total: int, desc: str) -> Any:
    """Tqdm on a terminal, :class:`LineBar` in a log (stderr not a terminal)."""
    if sys.stderr.isatty():
        from tqdm import tqdm

        return tqdm(total=total, desc=desc, unit="ep", file=sys.stderr)
    return LineBar(total, desc)


class SweepProgress(Callback):
    """Hydra callback: the sweep's progress bar, and its cost at the end (module notes)."""

    def __init__(self) -> None:
        self._stop: Any = None
        self._thread: Any = None
        self.sweep_dir: Path | None = None

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the thread: Hydra ships its callbacks to every joblib worker."""
        return {"_stop": None, "_thread": None, "sweep_dir": None}

    def on_multirun_start(self, config: Any, **kwargs: Any) -> None:
        """Start the polling thread for the sweep directory."""
        from amex.app.session import OUTPUT, STARTED
        from amex.app.sweeps import is_ours, job_value, sweep_jobs
        from amex.experiment.shards import shard_envs

        self._started = STARTED
        self._stop = threading.Event()
        self.sweep_dir = sweep_dir = Path(str(config.hydra.sweep.dir))
        self._before = summary_stamps(sweep_dir)  # an earlier sweep's jobs do not count
        OUTPUT["dir"] = sweep_dir
        SWEEPS.append(self)
        overrides = [str(o) for o in config.hydra.overrides.task]
        sweeper = config.hydra.sweeper
        params: Any = OmegaConf.to_container(sweeper.params) if sweeper.get("params") else {}
        ours = is_ours(sweeper)
        grids: Any = None
        if ours and sweeper.get("grids"):
            grids = OmegaConf.to_container(sweeper.grids)
        total = 0
        shards = int(config.get("shards") or 1)
        for job in sweep_jobs(params, grids, overrides, shards, expand=ours):
            episodes = int(job_value(job, "episodes", config.episodes))
            shards = int(job_value(job, "shards", config.get("shards") or 1))
            total += len(shard_envs(episodes, shards, int(job_value(job, "shard", 0))))
        self._thread = threading.Thread(
            target=self._poll, args=(sweep_dir, total), name="amex-sweep-progress", daemon=True
        )
        self._thread.start()

    def _poll(self, sweep_dir: Path, total: int) -> None:
        seen = dict(self._before)
        with progress_bar(total, f"sweep {sweep_dir.name}") as bar:
            while True:
                stopping = self._stop.wait(0.5)
                done = 0
                for path in sweep_dir.glob("*/episodes.csv"):
                    with contextlib.suppress(OSError):  # a file being replaced
                        done += max(path.read_bytes().count(b"\n") - 1, 0)
                for name, record in job_records(sweep_dir, seen).items():  # jobs just finished
                    if "success" in record:
                        bar.write(f"{name}: {run_line(record)}")
                seen = summary_stamps(sweep_dir)
                bar.update(min(done, total) - bar.n)
                if stopping:
                    return

    def stop(self) -> None:
        """Final count, then stop the thread."""
        if self._stop is not None:
            self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        """Stop the bar and print what the sweep cost."""
        from amex.app.processes import tree_cpu_time

        self.stop()
        if self.sweep_dir is None:
            return
        tic = self._started  # the command's start: its checks count too
        launcher = str(OmegaConf.select(config, "hydra.launcher._target_", default=""))
        elsewhere = launcher.endswith("SlurmLauncher")  # submitit's: the jobs run on the cluster
        wall = time.perf_counter() - tic
        cost = sweep_cost(self.sweep_dir, self._before, wall, tree_cpu_time(), elsewhere)
        say(describe(self.sweep_dir, cost))
