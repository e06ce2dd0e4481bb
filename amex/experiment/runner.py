"""A run: the reference plan, then ``episodes`` environments of one task with one method.

Writes into the run directory ``episodes.csv`` (one row per episode, appended durably as each
episode ends; see :mod:`amex.experiment.store`) and ``summary.json`` (the aggregates of the
requested
episodes and the run's own wall and CPU time, replaced atomically at the end; removed when a run
starts, so it never describes an earlier run); a sharded run (``shards > 1``) executes only its
share of the environments and says which in ``shard.json`` (:mod:`amex.experiment.shards`). No Hydra
here: :func:`run` takes a :class:`~amex.experiment.config.RunConfig` and a directory, so scripts
can call
it directly. Everything is checked before anything is written
(:func:`preflight`), and the directory is locked while the run writes
(:class:`~amex.core.durable.RunLock`): a second run into it is refused.
"""

from __future__ import annotations

import contextlib
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from amex.control.osc import OSCGains
from amex.core.durable import RunLock, replace_durably
from amex.core.errors import ConfigError, WriteError
from amex.core.schema import field_names
from amex.experiment.config import RunConfig, validate
from amex.experiment.shards import ShardSpec, write_spec
from amex.experiment.store import EpisodeStore
from amex.methods import Method, get_method
from amex.plan.cache import reference_costs, reference_plan
from amex.plan.reference import ReferencePlan
from amex.robot import RobotModel, load_robot
from amex.robot.geometry import joint_metric
from amex.sim.episode import run_episode
from amex.sim.loop import LoopConfig, Recorder
from amex.sim.metrics import EpisodeResult, summarize
from amex.sim.scenario import (
    Scenario,
    ScenarioConfig,
    make_scenario,
    plan_goal,
    with_reference_goal,
)

log = logging.getLogger(__name__)

EPISODES_CSV = "episodes.csv"
SUMMARY_JSON = "summary.json"


@dataclass(frozen=True)
class RunContext:
    """What every episode of a run shares: the robot and the reference plan."""

    robot: RobotModel
    plan: ReferencePlan


def stand_in_plan(robot: RobotModel, config: RunConfig) -> ReferencePlan:
    """A plan of the reference plan's shape, without solving: at rest in q0, y straight to the goal.

    Methods check their parameters against it (:func:`preflight`) in milliseconds.
    """
    n = config.plan.steps + 1
    y0 = robot.task_position(robot.q0)
    goal_pos = plan_goal(config.scene(), config.task, robot.tcp_pose(robot.q0).translation)
    goal = np.concatenate([goal_pos, config.scenario.goal_axis])
    u = np.linspace(0.0, 1.0, n)[:, None]
    y = (1.0 - u) * y0 + u * goal
    metric = joint_metric(config.plan.metric, robot.nv)
    q = np.repeat(robot.q0[None], n, axis=0)
    return ReferencePlan(q=q, y=y, dt=config.plan.dt, metric=metric)


def preflight(config: RunConfig) -> None:
    """Validate ``config`` and build what a run builds from it, cheaply; nothing is written.

    The robot is loaded, the plan's costs and the method are built (the method on
    :func:`stand_in_plan`), so a bad value anywhere raises :class:`ConfigError` here, before a run
    directory exists, instead of in the first episode.
    """
    validate(config)
    robot = load_robot(config.robot)
    reference_costs(robot, config.plan)
    name = config.method.name
    try:
        get_method(name, config.implementation)(
            stand_in_plan(robot, config), config.method_config(), 1.0 / config.outer_hz, robot
        )
    except ConfigError as e:
        message = str(e)
        param = message.removeprefix("invalid ").split("=", 1)[0]
        if message.startswith("invalid ") and param in field_names(config.method):
            raise ConfigError(f"invalid method.{message.removeprefix('invalid ')}") from e
        raise ConfigError(f"method={name}: {message}") from e
    except Exception as e:  # a plugin's own checks may raise anything
        raise ConfigError(f"method={name} cannot be built from its parameters: {e}") from e


def prepare(config: RunConfig) -> RunContext:
    """Load the robot and get the reference plan (solved, or from the disk cache)."""
    robot = load_robot(config.robot)
    plan = reference_plan(
        robot,
        config.plan,
        plan_goal(config.scene(), config.task, robot.tcp_pose(robot.q0).translation),
        np.asarray(config.scenario.goal_axis, dtype=float),
    )
    return RunContext(robot, plan)


@dataclass(frozen=True)
class EpisodeSetup:
    """What the episodes of one configuration share, in the lower layers' own types.

    Built once per run from the :class:`~amex.experiment.config.RunConfig` (:func:`setup`):
    every length is in the scene's units, so nothing below the experiment layer sees the run's
    configuration or converts a unit.

    Attributes:
        context: the robot and the reference plan.
        task: the task, 0-4.
        seed: the scene seed.
        scene: the scene distributions in scene units, reference goal stated.
        method: the method's class (``implementation`` resolved).
        params: the method's parameters in scene units.
        outer_dt: the outer period [s].
        gains: the inner controller's gains, the method's task gains included.
        loop: the episode loop's rates and stopping rules.
        world: perception, prediction, mismatch and disturbance compensation of the episode.
        log_compression: how a log of an episode compresses its chunks (``lz4``, ``zstd``,
            ``none``; :func:`amex.log.writer.write_options`).
    """

    context: RunContext
    task: int
    seed: int
    scene: ScenarioConfig
    method: type[Method]
    params: Any
    outer_dt: float
    gains: OSCGains
    loop: LoopConfig
    world: dict[str, Any]
    log_compression: str


def setup(config: RunConfig, context: RunContext) -> EpisodeSetup:
    """The per-run conversion of ``config`` for its episodes (:class:`EpisodeSetup`)."""
    return EpisodeSetup(
        context=context,
        task=config.task,
        seed=config.seed,
        scene=with_reference_goal(config.scene(), context.plan.y[0, :3]),
        method=get_method(config.method.name, config.implementation),
        params=config.method_config(),
        outer_dt=1.0 / config.outer_hz,
        gains=config.gains(),
        loop=config.loop,
        world={
            "perception": config.perception,
            "prediction": config.prediction,
            "mismatch": config.mismatch,
            "disturbance": config.controller.compensation(),
        },
        log_compression=config.log_compression,
    )


def run_setup(setup: EpisodeSetup, env: int, log_path: Path | None = None) -> EpisodeResult:
    """Environment ``env`` of ``setup``'s task with its method; logged as MCAP to ``log_path``."""
    if log_path is None:
        return run_setup_with(setup, env, None)
    from amex.log import EpisodeLogger

    context = setup.context
    method, scenario = _method(setup), _scenario(setup, env)  # before the log's file is made
    metadata = {"task": setup.task, "method": method.name, "env": env, "seed": setup.seed}
    args = (log_path, context.robot, context.plan, scenario, metadata)
    fresh = method.fresh_steps  # its steps are kept without copies
    with EpisodeLogger(*args, compression=setup.log_compression, fresh_steps=fresh) as logger:
        return _episode(setup, method, scenario, logger)


def run_setup_with(setup: EpisodeSetup, env: int, recorder: Recorder | None) -> EpisodeResult:
    """Environment ``env`` of ``setup``'s task with its method, its steps given to ``recorder``."""
    return _episode(setup, _method(setup), _scenario(setup, env), recorder)


def _method(setup: EpisodeSetup) -> Method:
    context = setup.context
    return setup.method(context.plan, setup.params, setup.outer_dt, context.robot)


def _scenario(setup: EpisodeSetup, env: int) -> Scenario:
    plan = setup.context.plan
    return make_scenario(setup.scene, setup.task, setup.seed, env, plan.y[0, :3], plan.duration)


def _episode(
    setup: EpisodeSetup, method: Method, scenario: Scenario, recorder: Recorder | None
) -> EpisodeResult:
    context = setup.context
    args = (context.robot, method, scenario, setup.gains, setup.loop)
    world = {**setup.world, "reference_path": context.plan.y[:, :3]}
    return run_episode(*args, recorder, **world)


def run_one(
    config: RunConfig, context: RunContext, env: int, log_path: Path | None = None
) -> EpisodeResult:
    """Environment ``env`` of the configured task, executed with the configured method.

    With ``log_path``, the episode is logged there as MCAP (:class:`amex.log.EpisodeLogger`).
    A run converts its configuration once (:func:`setup`) and calls :func:`run_setup`.
    """
    return run_setup(setup(config, context), env, log_path)


def run(
    config: RunConfig,
    run_dir: Path,
    progress: Callable[[int, EpisodeResult], None] | None = None,
    ready: Callable[[], None] | None = None,
) -> dict:
    """Execute the run into ``run_dir``; return the summary (also written as ``summary.json``).

    Environments already in ``run_dir/episodes.csv`` under the same configuration hash are
    skipped (resume after a crash or Ctrl-C); ``progress`` is called for those too, first.
    ``ready`` is called once, when the episodes are set up (the modules of the log imported
    for ``log=full``) and before the first runs: ``amex-run`` freezes the heap there
    (:func:`amex.app.heap.settle`), so that the episodes' collections do not walk the set-up.

    Raises:
        ConfigError: a bad configuration (before anything is written).
        LockedError: another run is writing into ``run_dir``.
        WriteError: a row or the summary could not be written (e.g. a full disk); every row
            written before is kept and the same call resumes.
    """
    preflight(config)
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise WriteError(run_dir, e.strerror or str(e)) from e
    with RunLock(run_dir):
        return _run_locked(config, run_dir, progress, ready)


def _run_locked(
    config: RunConfig,
    run_dir: Path,
    progress: Callable[[int, EpisodeResult], None] | None,
    ready: Callable[[], None] | None,
) -> dict:
    started = time.perf_counter(), time.process_time()
    store = EpisodeStore.for_config(run_dir / EPISODES_CSV, config)
    with contextlib.suppress(OSError):  # from an earlier run; written anew at the end
        (run_dir / SUMMARY_JSON).unlink()
    envs = config.envs
    if config.shards > 1:
        write_spec(run_dir, ShardSpec(config.shard, config.shards, config.episodes))
    for env in sorted(store.done):
        if env in envs and progress is not None:
            progress(env, store.done[env])
    todo = [env for env in envs if env not in store.done]
    log.info(
        "task %d %s, %d episodes%s into %s (config hash %s, scene hash %s); %d recorded earlier, "
        "%d to run",
        config.task,
        config.method.name,
        len(envs),
        f" (shard {config.shard} of {config.shards} of {config.episodes})"
        if config.shards > 1
        else "",
        run_dir,
        store.config_hash,
        store.scene_hash,
        len(envs) - len(todo),
        len(todo),
    )
    if todo:
        episodes = setup(config, prepare(config))
        if config.log == "full":
            import amex.log.writer  # noqa: F401  (set-up: imported before ``ready``)
    if ready is not None:
        ready()
    for env in todo:
        log_path = None
        if config.log == "full":
            log_path = run_dir / "logs" / f"episode_{env:03d}.mcap"
        result = run_setup(episodes, env, log_path)
        store.append(result)
        log.info(
            "env %d: %s, final distance %.4f m at %.2f s, sum sq. acc. %.4g%s%s",
            env,
            "success" if result.success else "no success",
            result.final_distance,
            result.final_time,
            result.sum_sq_acc,
            ", collided" if result.collided else "",
            f", failure: {result.failure}" if result.failure else "",
        )
        if progress is not None:
            progress(env, result)
    results = [store.done[env] for env in envs]
    summary = summarize(results, ddof=config.std_ddof)
    summary.update(
        {
            "task": config.task,
            "method": config.method.name,
            "seed": config.seed,
            "config_hash": store.config_hash,
            "scene_hash": store.scene_hash,
        }
    )
    if config.shards > 1:
        summary.update({"shard": config.shard, "shards": config.shards})
    summary["recorded"] = len(store.done)  # rows in episodes.csv, >= episodes after a shorter rerun
    # this run's own cost (the episodes it ran, not those kept): what a sweep reports at its end
    summary["wall_time"] = time.perf_counter() - started[0]
    summary["cpu_time"] = time.process_time() - started[1]
    replace_durably(run_dir / SUMMARY_JSON, (json.dumps(summary, indent=2) + "\n").encode())
    log.info(
        "done: success %.3f, final time %.2f +- %.2f s, %d failures; wrote %s",
        summary["success"]["mean"],
        summary["final_time"]["mean"],
        summary["final_time"]["two_std"],
        summary["failures"],
        run_dir / SUMMARY_JSON,
    )
    return summary
