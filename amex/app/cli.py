"""Command-line entry points: ``amex-run`` (Hydra) and, later, ``amex-log``.

``amex-run`` first composes and validates every configuration the command line asks for (each
combination of a ``-m`` sweep) with Hydra's compose API, builds each method from its parameters
(:func:`amex.experiment.runner.preflight`) and checks the launcher and the output directory
(:mod:`amex.app.launch`); any bad value gets one line on stderr and exit code 2 before Hydra
creates a
run directory. Only then does Hydra run the job(s). A job's failure (a full disk, a locked
directory) is one line too, with the number of episodes kept; Ctrl-C and SIGTERM stop the run or
the whole sweep, workers included, and say that the same command resumes. Only this module and
:mod:`amex.app.launch` import Hydra or OmegaConf. ``AMEX_DEBUG=1`` shows tracebacks.
"""

from __future__ import annotations

import os
import time

STARTED = time.perf_counter()  # the command's start, for the sweep's closing line

# One BLAS/OpenMP thread per process: episodes are tiny linear algebra, and sweeps run one job
# per core. Set before numpy is imported anywhere.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import dataclasses  # noqa: E402
import logging  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")
PROG = "amex-run"
#: Where this process's run or sweep writes (for the closing line of a stop or a failure).
_OUTPUT: dict[str, Path] = {}


class UsageError(Exception):
    """A bad command line; the message is the one line shown to the user."""


def shard_suffix(shard: Any, shards: Any) -> str:
    """``${amex.shard:${shard},${shards}}`` in directory names: ``_shard2of7``, or nothing."""
    try:
        count = int(shards)
    except (TypeError, ValueError):
        return f"_shard{shard}of{shards}"
    return f"_shard{shard}of{count}" if count != 1 else ""


def _register_resolvers() -> None:
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver("amex.shard"):
        OmegaConf.register_new_resolver("amex.shard", shard_suffix)


_register_resolvers()  # also in sweep workers, which import this module to run a job


def _register_schemas() -> None:
    from hydra.core.config_store import ConfigStore

    from amex.experiment.config import RunConfig
    from amex.methods import BUILTIN_METHODS, METHODS

    cs = ConfigStore.instance()
    cs.store(name="run_schema", node=RunConfig)
    for name, cls in METHODS.items():
        cs.store(group="method", name=f"schema_{name}", node=cls.config_class)
        if name not in BUILTIN_METHODS:  # a plugin: ``method=<name>`` is its dataclass's defaults
            cs.store(group="method", name=name, node=cls.config_class)


def explain(error: Exception, overrides: list[str] | None = None) -> str:
    """Turn a Hydra/OmegaConf composition error into one line naming value and choices."""
    from amex.app.launch import group_options, valid_keys
    from amex.methods import METHODS
    from amex.sim.scenario import TASKS

    parts: list[str] = []
    seen: Exception | None = error
    while seen is not None and len(parts) < 10:  # the whole cause chain: Hydra wraps OmegaConf
        parts.append(str(seen))
        seen = seen.__cause__ or seen.__context__  # type: ignore[assignment]
    text = "\n".join(parts)
    m = re.search(r"Could not find '([\w/]+)/([^'/]*)'", text)
    if m:
        group, value = m.groups()
        if group == "method":
            return f"invalid method={value!r}; valid: {', '.join(sorted(METHODS))}"
        options = group_options(group)
        if options:
            return f"invalid {group}={value!r}; valid: {', '.join(options)}"
        return f"invalid {group}={value!r}; see `{PROG} --help` for the options of {group}"
    m = re.search(r"Could not override '([^']+)'", text) or re.search(
        r"Key '([^']+)' is not in struct", text
    )
    if m:
        return f"unknown config key {m.group(1)!r}; {valid_keys(m.group(1), overrides or [])}"
    m = re.search(r"Value '([^']*)' (?:of type '\w+' )?could not be converted to (\w+)", text)
    if m:
        key = re.search(r"full_key: (\S+)", text) or re.search(r"override ([\w.]+)=", text)
        name = key.group(1) if key else "value"
        if name == "task":
            return f"invalid task={m.group(1)!r}; valid: {', '.join(map(str, TASKS))}"
        return f"invalid {name}={m.group(1)!r}; valid: a value of type {m.group(2)}"
    first = text.strip().splitlines()[0] if text.strip() else type(error).__name__
    return first


def _parse(overrides: list[str]) -> list[Any]:
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        return OverridesParser.create().parse_overrides(overrides)
    except Exception as e:  # Hydra's OverrideParseException and friends
        raise UsageError(f"invalid override: {explain(e, overrides)}") from e


def command_line_jobs(overrides: list[str], multirun: bool) -> tuple[list[list[str]], list[str]]:
    """The jobs the command line describes (one unless ``multirun``) and its ``hydra.*`` part.

    A sweep's jobs are those its sweeper launches (:func:`amex.app.sweeps.sweep_jobs`): the command
    line's and ``hydra.sweeper.params``'s product, ``hydra.sweeper.grids``, every shard.
    """
    from amex.app.launch import LaunchError, sweep_settings
    from amex.app.sweeps import sweep_jobs

    parsed = _parse(overrides)
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
        return sweep_jobs(params, grids, task, shards, expand=ours), hydra_overrides
    except Exception as e:  # a bad value in hydra.sweeper.params or grids
        raise UsageError(f"invalid sweep: {explain(e, overrides)}") from e


def load_config(overrides: list[str]) -> Any:
    """Compose ``conf/config.yaml`` with ``overrides`` and return a validated ``RunConfig``."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from omegaconf import OmegaConf

    from amex.core.errors import ConfigError
    from amex.experiment.config import validate

    for override in overrides:  # the typed schemas behind the methods are not methods
        key, _, value = override.lstrip("+~").partition("=")
        if key == "method" and value.startswith("schema_"):
            from amex.methods import METHODS

            raise UsageError(f"invalid method={value!r}; valid: {', '.join(sorted(METHODS))}")
    _register_schemas()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            cfg = compose(config_name="config", overrides=overrides)
        config: Any = OmegaConf.to_object(cfg)
    except ConfigError:
        raise
    except Exception as e:  # Hydra and OmegaConf raise many types for bad input
        raise UsageError(explain(e, overrides)) from e
    finally:
        GlobalHydra.instance().clear()
    validate(config)
    return config


def _validate_command_line(argv: list[str]) -> None:
    """Compose and validate every run the command line describes, or raise :class:`UsageError`.

    The jobs of one cell that differ only in ``shard`` share one check of their configuration;
    every job's directory must be its own (a subdir without ``${amex.shard:...}`` is refused).
    """
    from amex.app.launch import LaunchError, check_launch
    from amex.app.sweeps import job_value
    from amex.core.errors import ConfigError
    from amex.experiment.runner import preflight
    from amex.experiment.shards import ShardSpec

    flags_with_value = {"--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd"}
    overrides: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
            continue
        if arg in flags_with_value:
            skip = True
            continue
        if arg.startswith("-"):
            continue
        overrides.append(arg)
    multirun = "-m" in argv or "--multirun" in argv
    jobs, hydra_overrides = command_line_jobs(overrides, multirun)
    checked: dict[tuple[str, ...], Any] = {}
    owners: dict[Path, list[str]] = {}
    for job in jobs:
        cell = tuple(o for o in job if o.split("=", 1)[0].lstrip("+") != "shard")
        try:
            if cell not in checked:
                config = load_config(job)
                preflight(config)
                job_dir = check_launch(job, hydra_overrides, multirun, check_dir=not checked)
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
        _check_resumable(job_dir, config)


def _shard_dir(first_dir: Path, first: Any, shard: int) -> Path | None:
    """Shard ``shard``'s directory from the one of the cell's first checked shard, if named so."""
    suffix = shard_suffix(first.shard, first.shards)
    if not suffix or suffix not in first_dir.name:
        return None
    return first_dir.with_name(first_dir.name.replace(suffix, shard_suffix(shard, first.shards)))


def _check_resumable(run_dir: Path, config: Any) -> None:
    """Refuse a run directory that holds episodes of another configuration (before Hydra writes)."""
    from amex.experiment.store import EpisodeStore, StoreError, config_hash

    path = run_dir / "episodes.csv"
    if not path.exists():
        return
    try:
        EpisodeStore.check(path, config_hash(config))
    except StoreError as e:
        raise UsageError(str(e)) from e


def _fail(message: str) -> None:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    raise SystemExit(2)


def _kept_episodes(run_dir: Path, config: Any) -> int:
    """How many of the run's environments ``run_dir/episodes.csv`` already holds (0 if none)."""
    from amex.experiment.store import EpisodeStore, StoreError, config_hash

    path = run_dir / "episodes.csv"
    if not path.exists() or path.stat().st_size == 0:
        return 0
    try:
        rows = EpisodeStore.check(path, config_hash(config))
    except StoreError:
        return 0  # the run itself reports it
    return len({int(r["env"]) for r in rows} & set(config.envs))


def _task(cfg: Any) -> None:
    """The Hydra job: one run into Hydra's output directory, with a progress bar."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode
    from omegaconf import OmegaConf
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    from amex.app.launch import job_guard
    from amex.app.processes import Interrupted
    from amex.experiment.runner import run

    config: Any = OmegaConf.to_object(cfg)
    logging.raiseExceptions = False  # run.log is a record: a full disk must not print tracebacks
    hydra_config = HydraConfig.get()
    run_dir = Path(hydra_config.runtime.output_dir)
    label = f"task {config.task} {config.method.name}"
    if config.shards > 1:
        label += f" shard {config.shard}/{config.shards}"
    episodes = len(config.envs)
    quiet = hydra_config.mode == RunMode.MULTIRUN  # the sweep has one bar (SweepProgress)
    _OUTPUT.setdefault("dir", run_dir)
    if quiet:  # no tqdm in sweep workers: its lock is a semaphore, which a killed worker leaks
        try:
            with job_guard(run_dir, multirun=True):
                summary = run(config, run_dir)
        except Interrupted as e:
            if not os.environ.get("SUBMITIT_EXECUTOR"):
                raise  # a local worker: the launcher reports the stop
            # A submitit job (SLURM's SIGTERM on scancel, preemption or requeue): its log ends
            # with the closing line, and the exit code says it stopped (no result is pickled,
            # so the launcher never takes the partial run for a finished one).
            line, code = _closing_line(e)
            print(line, file=sys.stderr, flush=True)
            raise SystemExit(code) from None
    else:
        with (
            job_guard(run_dir, multirun=False),
            logging_redirect_tqdm(),
            tqdm(total=episodes, desc=label, unit="ep") as bar,
        ):
            for handler in logging.getLogger().handlers:  # tqdm's console handler: warnings
                if type(handler).__name__ == "_TqdmLoggingHandler":  # only; the record: run.log
                    handler.setLevel(logging.WARNING)
            successes = done = 0

            def progress(env: int, result: Any) -> None:
                nonlocal successes, done
                successes += int(result.success)
                done += 1
                bar.set_postfix(success=f"{successes}/{done}")
                bar.update(1)

            kept = _kept_episodes(run_dir, config)
            if kept:
                bar.write(
                    f"resuming {run_dir}: kept {kept} of {episodes} episodes recorded earlier, "
                    f"running the other {episodes - kept}",
                    file=sys.stderr,
                )
            summary = run(config, run_dir, progress)
    s = summary["success"]["mean"]
    t = summary["final_time"]
    print(
        f"{label}: success {s:.3f}  final time {t['mean']:.2f} +- {t['two_std']:.2f} s  "
        f"({summary['failures']} failures)",
        file=sys.stderr,
    )
    print(run_dir, flush=True)


def _closing_line(error: BaseException) -> tuple[str, int]:
    """The last line of a stopped or failed run, and its exit code."""
    from amex.app.launch import JobFailed
    from amex.app.processes import count_rows, signal_code

    directory = _OUTPUT.get("dir")
    kept = f"{count_rows(directory)} episodes kept in {directory}" if directory else ""
    if isinstance(error, OSError):  # e.g. Hydra writing .hydra/ on a full disk
        what = f"cannot write {error.filename}" if error.filename else "a write failed"
        error = JobFailed(f"{what}: {error.strerror or error}", True)
    elif isinstance(error, Exception):  # anything else Hydra or a job raised
        first = (str(error).strip().splitlines() or [""])[0]
        error = JobFailed(f"{type(error).__name__}: {first} (AMEX_DEBUG=1 shows the traceback)")
    if isinstance(error, JobFailed):
        if not error.resumable:
            return f"{PROG}: error: {error.message}", 2
        tail = f"; {kept}; fix the cause and run the same command to resume" if kept else ""
        return f"{PROG}: error: {error.message}{tail}", 2
    name = str(error) or "SIGINT"
    tail = f": {kept}; the same command resumes" if kept else ": nothing written yet"
    return f"{PROG}: stopped by {name}{tail}", signal_code(error)


def run_main() -> None:
    """``amex-run``: validate the command line, then hand it to Hydra."""
    from amex.app.launch import JobFailed
    from amex.app.processes import LAUNCHER_PID, signals_raise

    multirun_flags = [a for a in sys.argv[1:] if a in ("-m", "--multirun")]
    argv = multirun_flags + [a for a in sys.argv[1:] if a not in multirun_flags]
    sys.argv[1:] = argv  # Hydra's parser wants -m before the overrides; accept it anywhere
    debug = os.environ.get("AMEX_DEBUG") == "1"
    if "--help" in argv or "-h" in argv:
        from amex.app.usage import help_text

        sys.stdout.write(help_text(Path(CONF_DIR), PROG))
        return
    informational = {"--help", "-h", "--hydra-help", "--info", "-i", "--cfg", "-c", "--version"}
    from amex.app.progress import SWEEPS

    try:
        with signals_raise():
            if not informational.intersection(argv):
                try:
                    _validate_command_line(argv)
                except UsageError as e:
                    if debug:
                        raise
                    _fail(str(e))
            import hydra

            _register_schemas()
            main = hydra.main(config_path=CONF_DIR, config_name="config", version_base="1.3")(
                _task
            )
            os.environ[LAUNCHER_PID] = str(os.getpid())  # sweep workers stop with this process
            os.environ["HYDRA_FULL_ERROR"] = "1"  # Hydra re-raises its errors, we print one line
            main()
    except (JobFailed, KeyboardInterrupt, Exception) as e:
        if debug:
            raise
        for callback in SWEEPS:  # stop the sweep's progress bar before the last line
            callback.stop()
        line, code = _closing_line(e)
        print(line, file=sys.stderr, flush=True)
        raise SystemExit(code) from None
