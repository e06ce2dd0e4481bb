"""What ``amex-run`` does around Hydra: checks before anything is launched, a guard around each job.

Before Hydra creates a directory (:func:`check_launch`): the Hydra part of the command line is
composed too (``hydra/launcher=nope``), a joblib launcher's options are checked by joblib itself
(``hydra.launcher.n_jobs=0``), the output directory must be creatable and writable and not be held
by another run (:class:`~amex.core.durable.RunLock`).

Around each job (:func:`job_guard`): in a sweep worker, Ctrl-C is left to the launching process
(which stops the sweep and kills its workers), SIGTERM stops the job cleanly, and the worker stops
itself when the launching process dies (:func:`amex.app.processes.watch_parent`). A failure becomes
:class:`JobFailed`, whose one-line message the launching process prints, with the number of
episodes kept.

Like :mod:`amex.app.cli`, this module imports Hydra; library code does not.
"""

from __future__ import annotations

import contextlib
import os
import signal
from collections.abc import Iterator
from dataclasses import is_dataclass
from pathlib import Path
from typing import Any

from amex.app.processes import LAUNCHER_PID, Interrupted, signals_raise, watch_parent
from amex.core.durable import RunLock, WriteError
from amex.core.errors import AmexError


class LaunchError(Exception):
    """The command line cannot be launched; the message is the one line shown."""


class JobFailed(BaseException):
    """A job stopped with an error (a BaseException, so Hydra does not print it as a traceback).

    Attributes:
        message: the line to show.
        resumable: whether the closing line should say that the same command resumes.
    """

    def __init__(self, message: str, resumable: bool = False) -> None:
        super().__init__(message, resumable)
        self.message = message
        self.resumable = resumable


def group_options(group: str) -> list[str]:
    """The options of a Hydra config group (``method``, ``hydra/launcher``, ``experiment``)."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from amex.app.cli import CONF_DIR

    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            names = GlobalHydra.instance().config_loader().get_group_options(group)
    except Exception:  # only for a message: never fail because of it
        return []
    finally:
        GlobalHydra.instance().clear()
    return sorted(n for n in names if not n.startswith(("schema_", "_")))


def valid_keys(key: str, overrides: list[str]) -> str:
    """``valid keys of <node>: ...`` for the node an unknown dotted ``key`` was meant for."""
    from amex.experiment.config import RunConfig
    from amex.methods import METHODS

    chosen = [o.split("=", 1)[1] for o in overrides if o.startswith("method=")]
    method = chosen[-1] if chosen else "amex"
    node: Any = RunConfig()
    if method in METHODS:
        node.method = METHODS[method].config_class()
    parents = key.lstrip("+").split(".")[:-1]
    for name in parents:
        child = getattr(node, name, None)
        if not is_dataclass(child):
            break
        node = child
    else:
        names = [f for f in vars(node) if not f.startswith("_")]
        where = f" of {'.'.join(parents)}" if parents else ""
        return f"valid keys{where}: {', '.join(names)}"
    return f"valid keys: {', '.join(vars(RunConfig()))}"


def _check_joblib(launcher: Any) -> None:
    from joblib import Parallel, effective_n_jobs

    options = {k: v for k, v in launcher.items() if k != "_target_"}
    n_jobs = options.get("n_jobs")
    try:
        effective_n_jobs(n_jobs)
    except (TypeError, ValueError) as e:
        raise LaunchError(
            f"invalid hydra.launcher.n_jobs={n_jobs!r}; valid: a number of workers >= 1, or "
            f"-1 for all cores, -2 for all but one, ... (joblib: {e})"
        ) from e
    try:
        Parallel(**options)
    except (TypeError, ValueError) as e:
        raise LaunchError(f"invalid hydra.launcher options: {e}") from e


def check_output_dir(key: str, path: Path) -> None:
    """Refuse an output directory that is a file, cannot be created or written, or is locked.

    Locked: ``path`` itself or, for a sweep directory, one of its job directories.
    """
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        where = "it is" if probe == path else f"{probe} is"
        raise LaunchError(f"invalid {key}={str(path)!r}: {where} a file; valid: a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise LaunchError(
            f"invalid {key}={str(path)!r}: {probe} is not writable; valid: a writable directory"
        )
    holders = [d for d in (path, *(path.glob("*") if path.is_dir() else ())) if d.is_dir()]
    for directory in holders:
        holder = RunLock.holder(directory)
        if holder is not None:
            raise LaunchError(
                f"another amex-run is writing into {directory} ({holder}); wait for it to finish "
                f"or choose another {key}"
            )


@contextlib.contextmanager
def composed(overrides: list[str], hydra_overrides: list[str]) -> Iterator[Any]:
    """The config the command line composes (Hydra's part included), read inside the block.

    Any error Hydra or OmegaConf raise, composing or in the block, becomes one
    :class:`LaunchError` naming the bad override.
    """
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.utils import setup_globals

    from amex.app.cli import CONF_DIR, explain

    setup_globals()  # the ${now:...} resolver of the default directories
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            cfg = compose(
                config_name="config",
                overrides=[*overrides, *hydra_overrides],
                return_hydra_config=True,
            )
        yield cfg
    except Exception as e:  # Hydra and OmegaConf raise many types for bad input
        raise LaunchError(explain(e, overrides + hydra_overrides)) from e
    finally:
        GlobalHydra.instance().clear()


def check_launch(
    overrides: list[str], hydra_overrides: list[str], multirun: bool, check_dir: bool = True
) -> Path:
    """Compose a job's Hydra config, check its launcher and output directory; return the job's.

    For a sweep (``multirun``) that is ``hydra.sweep.dir / hydra.sweep.subdir``. ``check_dir``:
    check the launcher and the (sweep) directory, once per sweep.
    """
    from omegaconf import OmegaConf

    with composed(overrides, hydra_overrides) as cfg:
        hydra_cfg: Any = OmegaConf.to_container(cfg.hydra, resolve=False)
        key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
        chosen = str(OmegaConf.select(cfg, key) or "")
        directory = Path(chosen)
        subdir = str(OmegaConf.select(cfg, "hydra.sweep.subdir")) if multirun else ""
        job = directory / subdir
    if not chosen.strip():
        raise LaunchError(f"invalid {key}=''; valid: a directory path (runs/mine, /data/run1, ...)")
    if not check_dir:
        return job
    launcher = hydra_cfg.get("launcher") or {}
    if multirun and str(launcher.get("_target_", "")).endswith("JoblibLauncher"):
        _check_joblib(launcher)
    check_output_dir(key, directory)
    return job


def sweep_settings(
    overrides: list[str], hydra_overrides: list[str]
) -> tuple[dict[str, Any], dict[str, Any] | None, int, bool]:
    """``hydra.sweeper.params``, ``hydra.sweeper.grids`` and ``shards`` of a sweep's config.

    Composed from the command line's fixed (non-sweep) ``overrides``, e.g. ``study=...``; the
    last value says whether the sweeper is ``hydra/sweeper=amex`` (else: no grids, no shards
    added, :func:`amex.app.sweeps.sweep_jobs`).
    """
    from omegaconf import OmegaConf

    from amex.app.cli import _register_schemas
    from amex.app.sweeps import is_ours

    _register_schemas()
    with composed(overrides, hydra_overrides) as cfg:
        sweeper: Any = OmegaConf.to_container(cfg.hydra.sweeper, resolve=False)
        shards = int(cfg.get("shards") or 1)
    ours = is_ours(sweeper)
    return sweeper.get("params") or {}, sweeper.get("grids") if ours else None, shards, ours


@contextlib.contextmanager
def job_guard(run_dir: Path, multirun: bool) -> Iterator[None]:
    """Run one job: worker signal set-up, and every failure turned into :class:`JobFailed`."""
    launcher = int(os.environ.get(LAUNCHER_PID, "0") or 0)
    in_worker = multirun and launcher not in (0, os.getpid())
    watch = None
    previous_int = None
    if in_worker:
        previous_int = signal.signal(signal.SIGINT, signal.SIG_IGN)  # the launcher's to handle
        watch = watch_parent(launcher)
    try:
        with signals_raise((signal.SIGTERM,)):
            yield
    except Interrupted:
        if watch is not None and watch.orphaned.is_set():
            os._exit(128 + signal.SIGTERM)  # nobody left to report to; the rows are on disk
        raise
    except WriteError as e:
        raise JobFailed(str(e), resumable=True) from None
    except AmexError as e:
        raise JobFailed(str(e)) from None
    except OSError as e:
        raise JobFailed(f"{e.strerror or e}: {e.filename or run_dir}", resumable=True) from None
    finally:
        if watch is not None:
            watch.stop()
        if previous_int is not None:
            signal.signal(signal.SIGINT, previous_int)
