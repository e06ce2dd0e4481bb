"""What ``amex-run`` checks before Hydra runs anything: every job of the command line.

Each configuration the command line describes (each combination of a ``-m`` sweep, every shard) is
composed and validated, its method built from its parameters
(:func:`amex.experiment.runner.preflight`), its launcher's options and its output directory
checked, and a directory that holds episodes of another configuration refused; any bad value is
one :class:`~amex.core.errors.UsageError` line before Hydra creates a directory.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from amex.app.compose import (
    composed,
    explain,
    initialized,
    parse_overrides,
    refuse_schema_methods,
    run_config,
    shard_suffix,
    use_command_line,
    validated,
)
from amex.core.durable import RunLock
from amex.core.errors import (
    ConfigError,
    LaunchError,
    LockedError,
    StoreError,
    UsageError,
    WriteError,
)


def command_line_jobs(overrides: list[str], multirun: bool) -> tuple[list[list[str]], list[str]]:
    """The jobs the command line describes (one unless ``multirun``) and its ``hydra.*`` part.

    A sweep's jobs are those its sweeper launches (:func:`amex.app.sweeps.sweep_jobs`): the command
    line's and ``hydra.sweeper.params``'s product, ``hydra.sweeper.grids``, every shard.
    """
    from amex.app.sweeps import sweep_jobs

    parsed = parse_overrides(overrides)
    hydra_overrides = [o.input_line for o in parsed if o.is_hydra_override() and o.input_line]
    task = [o.input_line for o in parsed if not o.is_hydra_override() and o.input_line]
    if not multirun:
        return [task], hydra_overrides
    fixed = [o.input_line for o in parsed if not (o.is_hydra_override() or o.is_sweep_override())]
    try:
        params, grids, shards, ours = sweep_settings(fixed, hydra_overrides)
    except LaunchError as e:
        raise UsageError(str(e)) from e
    try:
        with initialized() as loader:  # glob(...) sweeps list a config group's options
            jobs = sweep_jobs(params, grids, task, shards, expand=ours, config_loader=loader)
        return jobs, hydra_overrides
    except UsageError:
        raise
    except Exception as e:  # a bad value in hydra.sweeper.params or grids
        raise UsageError(f"invalid sweep: {explain(e, overrides)}") from e


class Checked(NamedTuple):
    """What :func:`validate_command_line` checked.

    Attributes:
        dirs: the directories of the jobs, in launch order.
        cfg: a single run's composition (Hydra's part included) when it was composed through the
            run's own ``Hydra`` (``hydra``), which the run then uses; else None.
    """

    dirs: list[Path]
    cfg: Any = None


def validate_command_line(argv: list[str], hydra: Any = None) -> Checked:
    """Compose and validate every run the command line describes, or raise :class:`UsageError`.

    ``hydra``: a single run's ``Hydra`` (:func:`amex.app.launch.main_hydra`): its one
    composition is checked and returned, for the run to use.

    The jobs of one cell that differ only in ``shard`` share one check of their configuration;
    every job's directory must be its own (a subdir without ``${amex.shard:...}`` is refused).
    """
    from amex.app.sweeps import job_value
    from amex.experiment.runner import preflight
    from amex.experiment.shards import ShardSpec

    overrides = use_command_line(argv)
    multirun = "-m" in argv or "--multirun" in argv
    jobs, hydra_overrides = command_line_jobs(overrides, multirun)
    checked: dict[tuple[str, ...], Any] = {}
    owners: dict[Path, list[str]] = {}
    run_cfg = None
    for job in jobs:
        cell = tuple(o for o in job if o.split("=", 1)[0].lstrip("+") != "shard")
        try:
            if cell not in checked:
                config, job_dir, run_cfg = compose_job(
                    job,
                    hydra_overrides,
                    multirun,
                    not checked,
                    check_config=preflight,
                    hydra=None if multirun else hydra,
                )
                checked[cell] = (config, job_dir)
            else:  # another shard of a checked cell: its range and its directory
                first, first_dir = checked[cell]
                shard = int(job_value(job, "shard"))
                ShardSpec(shard, first.shards, first.episodes)
                config = dataclasses.replace(first, shard=shard)
                job_dir = _shard_dir(first_dir, first, shard) or check_launch(
                    job, hydra_overrides, multirun, check_dir=False
                )
        except (ConfigError, LaunchError) as e:
            raise UsageError(str(e)) from e
        except (TypeError, ValueError) as e:
            raise UsageError(f"invalid shard in {' '.join(job)}; valid: an integer") from e
        if job_dir in owners:
            raise UsageError(
                f"two jobs of the sweep write into {job_dir} ({' '.join(owners[job_dir])} and "
                f"{' '.join(job)}); valid: a hydra.sweep.subdir that tells them apart "
                "(with ${amex.shard:${shard},${shards}} for shards)"
            )
        owners[job_dir] = job
        check_own_files(job_dir)
        _check_resumable(job_dir, config)
    return Checked(list(owners), run_cfg if hydra is not None else None)


def launch_lock(job_dirs: list[Path], multirun: bool) -> RunLock | None:
    """The lock this command holds before Hydra writes anything: the run's, or the sweep's.

    Taken between the checks and Hydra's start, so that of two commands into one directory the
    second is refused before its Hydra has written a byte there (its ``.hydra/`` record or
    ``multirun.yaml``). A single run's job takes the same lock again (re-entrant); a sweep's
    jobs, in other processes, lock their own directories.

    Raises:
        LaunchError: another command holds it.
    """
    if not job_dirs:
        return None
    directory = job_dirs[0] if not multirun else Path(os.path.commonpath(job_dirs))
    if multirun and len(job_dirs) == 1:
        directory = job_dirs[0].parent
    try:
        directory.mkdir(parents=True, exist_ok=True)
        return RunLock(directory).acquire()
    except (LockedError, WriteError, OSError) as e:
        raise LaunchError(str(e)) from e


def _shard_dir(first_dir: Path, first: Any, shard: int) -> Path | None:
    """Shard ``shard``'s directory from the one of the cell's first checked shard, if named so."""
    suffix = shard_suffix(first.shard, first.shards)
    if not suffix or suffix not in first_dir.name:
        return None
    return first_dir.with_name(first_dir.name.replace(suffix, shard_suffix(shard, first.shards)))


def _check_resumable(run_dir: Path, config: Any) -> None:
    """Refuse a run directory that holds episodes of another configuration (before Hydra writes)."""
    from amex.experiment.store import EpisodeStore, config_hash

    path = run_dir / "episodes.csv"
    if not path.exists():
        return
    try:
        EpisodeStore.check(path, config_hash(config))
    except StoreError as e:
        raise UsageError(str(e)) from e


def kept_episodes(run_dir: Path, config: Any) -> int:
    """How many of the run's environments ``run_dir/episodes.csv`` already holds (0 if none)."""
    from amex.experiment.store import EpisodeStore, config_hash

    path = run_dir / "episodes.csv"
    if not path.exists() or path.stat().st_size == 0:
        return 0
    try:
        rows = EpisodeStore.check(path, config_hash(config))
    except StoreError:
        return 0  # the run itself reports it
    return len({int(r["env"]) for r in rows} & set(config.envs))


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


#: What Hydra and amex write in a run directory: none of it may be a link to elsewhere.
OWN_FILES = (
    ".hydra",
    ".hydra/config.yaml",
    ".hydra/hydra.yaml",
    ".hydra/overrides.yaml",
    "run.log",
    ".amex-run.lock",
    "episodes.csv",
    "summary.json",
    "shard.json",
    "logs",
)


def check_own_files(run_dir: Path) -> None:
    """Refuse a run directory where a file Hydra or amex write is a symbolic link.

    Writing through it would overwrite or append to the link's target, which may be any file of
    the user's (a run directory copied or unpacked from elsewhere).
    """
    for name in OWN_FILES:
        path = run_dir / name
        if path.is_symlink():
            raise LaunchError(
                f"invalid run directory {run_dir}: {name} is a symbolic link (to "
                f"{os.readlink(path)}); valid: a run directory whose files are its own (remove "
                "the link, or choose another directory)"
            )


def check_launch(
    overrides: list[str], hydra_overrides: list[str], multirun: bool, check_dir: bool = True
) -> Path:
    """Compose a job's Hydra config, check its launcher and output directory; return the job's.

    For a sweep (``multirun``) that is ``hydra.sweep.dir / hydra.sweep.subdir``. ``check_dir``:
    check the launcher and the (sweep) directory, once per sweep.
    """
    return compose_job(overrides, hydra_overrides, multirun, check_dir)[1]


def compose_job(
    overrides: list[str],
    hydra_overrides: list[str],
    multirun: bool,
    check_dir: bool = True,
    check_config: Callable[[Any], None] | None = None,
    hydra: Any = None,
) -> tuple[Any, Path, Any]:
    """One composition of a job: its validated ``RunConfig``, its checked directory and itself.

    The run's configuration and Hydra's part (launcher, directories) come from the same
    composition, so a command's check composes each cell once (:func:`check_launch`).
    ``check_config`` (e.g. :func:`amex.experiment.runner.preflight`) checks the configuration
    before the directories are. ``hydra``: compose through a single run's ``Hydra``
    (:func:`amex.app.compose.composed`).
    """
    from omegaconf import OmegaConf

    refuse_schema_methods(overrides)
    with composed(overrides, hydra_overrides, hydra) as cfg:
        hydra_cfg: Any = OmegaConf.to_container(cfg.hydra, resolve=False)
        key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
        chosen = str(OmegaConf.select(cfg, key) or "")
        directory = Path(chosen)
        subdir = str(OmegaConf.select(cfg, "hydra.sweep.subdir")) if multirun else ""
        job = directory / subdir
        config = run_config(cfg)
    config = validated(config)
    if check_config is not None:
        check_config(config)
    if not chosen.strip():
        raise LaunchError(f"invalid {key}=''; valid: a directory path (runs/mine, /data/run1, ...)")
    if not check_dir:
        return config, job, cfg
    launcher = hydra_cfg.get("launcher") or {}
    if multirun and str(launcher.get("_target_", "")).endswith("JoblibLauncher"):
        _check_joblib(launcher)
    check_output_dir(key, directory)
    return config, job, cfg


def sweep_settings(
    overrides: list[str], hydra_overrides: list[str]
) -> tuple[dict[str, Any], dict[str, Any] | None, int, bool]:
    """``hydra.sweeper.params``, ``hydra.sweeper.grids`` and ``shards`` of a sweep's config.

    Composed from the command line's fixed (non-sweep) ``overrides``, e.g. ``study=...``; the
    last value says whether the sweeper is ``hydra/sweeper=amex`` (else: no grids, no shards
    added, :func:`amex.app.sweeps.sweep_jobs`).
    """
    from omegaconf import OmegaConf

    from amex.app.sweeps import is_ours

    with composed(overrides, hydra_overrides) as cfg:
        sweeper: Any = OmegaConf.to_container(cfg.hydra.sweeper, resolve=False)
        shards = int(cfg.get("shards") or 1)
    ours = is_ours(sweeper)
    return sweeper.get("params") or {}, sweeper.get("grids") if ours else None, shards, ours
