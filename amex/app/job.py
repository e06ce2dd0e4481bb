"""The Hydra job of ``amex-run``: one run into Hydra's output directory, guarded.

:func:`task` is the function Hydra calls for every job (one run, or each job of a sweep, in a
worker process). :func:`job_guard` sets up a sweep worker's signals (Ctrl-C is the launching
process's to handle, SIGTERM stops the job cleanly, the worker stops itself when the launcher
dies: :func:`amex.app.processes.watch_parent`) and turns every failure into a
:class:`~amex.core.errors.JobFailed`, whose line the launching process prints with the number of
episodes kept.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from amex.app import compose  # noqa: F401 - registers the resolvers in sweep workers
from amex.app.checks import kept_episodes
from amex.app.processes import LAUNCHER_PID, signals_raise, watch_parent
from amex.app.session import OUTPUT, closing_line, say
from amex.core.errors import AmexError, Interrupted, JobFailed, WriteError


@contextlib.contextmanager
def job_guard(run_dir: Path, multirun: bool) -> Iterator[None]:
    """Run one job: worker signal set-up, and every failure turned into :class:`JobFailed`."""
    launcher = int(os.environ.get(LAUNCHER_PID, "0") or 0)
    in_worker = multirun and launcher not in (0, os.getpid())
    watch = None
    previous_int = None
    if in_worker:
        previous_int = signal.signal(signal.SIGINT, signal.SIG_IGN)  # the launcher's to handle
        watch = watch_parent(launcher, local=os.environ.get("SUBMITIT_EXECUTOR") != "slurm")
        if watch is not None and watch.orphaned.is_set():
            os._exit(128 + signal.SIGTERM)  # the launcher died before this job began: nobody waits
    try:
        with signals_raise((signal.SIGTERM,)):
            yield
    except Interrupted:
        if watch is not None and watch.orphaned.is_set():
            os._exit(128 + signal.SIGTERM)  # nobody left to report to; the rows are on disk
        raise
    except WriteError as e:
        raise JobFailed(e, resumable=True) from None
    except AmexError as e:
        raise JobFailed(e) from None
    except OSError as e:
        reason = f"{e.strerror or e}: {e.filename or run_dir}"
        raise JobFailed(AmexError(reason), resumable=True) from None
    finally:
        if watch is not None:
            watch.stop()
        if previous_int is not None:
            signal.signal(signal.SIGINT, previous_int)


def task(cfg: Any) -> None:
    """The Hydra job: one run into Hydra's output directory, with a progress bar."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from amex.app.heap import settle
    from amex.app.progress import console_warnings, progress_bar, run_line
    from amex.experiment.runner import run

    config: Any = OmegaConf.to_object(cfg)
    settle()  # the set-up's heap out of the collector's way (amex.app.heap)
    logging.raiseExceptions = False  # run.log is a record: a full disk must not print tracebacks
    hydra_config = HydraConfig.get()
    run_dir = Path(hydra_config.runtime.output_dir)
    label = f"task {config.task} {config.method.name}"
    if config.shards > 1:
        label += f" shard {config.shard}/{config.shards}"
    episodes = len(config.envs)
    quiet = hydra_config.mode == RunMode.MULTIRUN  # the sweep has one bar (SweepProgress)
    OUTPUT.setdefault("dir", run_dir)
    if quiet:  # no tqdm in sweep workers: its lock is a semaphore, which a killed worker leaks
        try:
            with job_guard(run_dir, multirun=True):
                summary = run(config, run_dir, ready=settle)
        except Interrupted as e:
            if not os.environ.get("SUBMITIT_EXECUTOR"):
                raise  # a local worker: the launcher reports the stop
            # A submitit job (SLURM's SIGTERM on scancel, preemption or requeue): its log ends
            # with the closing line, and the exit code says it stopped (no result is pickled,
            # so the launcher never takes the partial run for a finished one).
            line, code = closing_line(e)
            say(line)
            raise SystemExit(code) from None
    else:
        with (
            job_guard(run_dir, multirun=False),
            console_warnings(),
            progress_bar(episodes, label) as bar,
        ):
            successes = done = 0

            def progress(env: int, result: Any) -> None:
                nonlocal successes, done
                successes += int(result.success)
                done += 1
                bar.set_postfix(success=f"{successes}/{done}", refresh=False)
                bar.update(1)  # one refresh: the count and its successes together

            kept = kept_episodes(run_dir, config)
            if kept:
                bar.write(
                    f"resuming {run_dir}: kept {kept} of {episodes} episodes recorded earlier, "
                    f"running the other {episodes - kept}",
                    file=sys.stderr,
                )
            summary = run(config, run_dir, progress, ready=settle)
    if not quiet or os.environ.get("SUBMITIT_EXECUTOR"):  # a local sweep's launcher says it
        say(f"{label}: {run_line(summary)}")
    say(str(run_dir), sys.stdout)
