"""A run: the reference plan, then ``episodes`` environments of one task with one method.

Writes into the run directory ``episodes.csv`` (one row per episode, appended durably as each
episode ends; see :mod:`amex.store`) and ``summary.json`` (the aggregates). No Hydra here:
:func:`run` takes a validated :class:`~amex.config.RunConfig` and a directory, so scripts can
call it directly.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from amex.config import RunConfig, validate
from amex.episode import run_episode
from amex.methods import get_method
from amex.metrics import EpisodeResult, summarize
from amex.plan.cache import reference_plan
from amex.plan.reference import ReferencePlan
from amex.robot import RobotModel, load_robot
from amex.scenario import make_scenario
from amex.store import EpisodeStore, config_hash, scene_hash

log = logging.getLogger(__name__)

EPISODES_CSV = "episodes.csv"
SUMMARY_JSON = "summary.json"


@dataclass(frozen=True)
class RunContext:
    """What every episode of a run shares: the robot and the reference plan."""

    robot: RobotModel
    plan: ReferencePlan


def prepare(config: RunConfig) -> RunContext:
    """Load the robot and get the reference plan (solved, or from the disk cache)."""
    robot = load_robot(config.robot.name, tuple(config.robot.q0))
    plan = reference_plan(
        robot,
        config.plan,
        np.asarray(config.scenario.reference_goal, dtype=float),
        np.asarray(config.scenario.goal_axis, dtype=float),
    )
    return RunContext(robot, plan)


def run_one(
    config: RunConfig, context: RunContext, env: int, log_path: Path | None = None
) -> EpisodeResult:
    """Environment ``env`` of the configured task, executed with the configured method.

    With ``log_path``, the episode is logged there as MCAP (:class:`amex.log.EpisodeLogger`).
    """
    method_cls = get_method(config.method.name)
    method = method_cls.from_plan(context.plan, config.method, 1.0 / config.outer_hz, context.robot)
    scenario = make_scenario(
        config.scenario,
        config.task,
        config.seed,
        env,
        context.plan.y[0, :3],
        context.plan.duration,
    )
    world: dict[str, Any] = {
        "perception": config.perception,
        "prediction": config.prediction,
        "mismatch": config.mismatch,
        "disturbance": config.controller.compensation(),
    }
    if log_path is None:
        return run_episode(context.robot, method, scenario, config.gains(), config.loop, **world)
    from amex.log import EpisodeLogger

    metadata = {"task": config.task, "method": config.method.name, "env": env, "seed": config.seed}
    with EpisodeLogger(log_path, context.robot, context.plan, scenario, metadata) as logger:
        return run_episode(
            context.robot, method, scenario, config.gains(), config.loop, logger, **world
        )


def run(
    config: RunConfig,
    run_dir: Path,
    progress: Callable[[int, EpisodeResult], None] | None = None,
) -> dict:
    """Execute the run into ``run_dir``; return the summary (also written as ``summary.json``).

    Environments already in ``run_dir/episodes.csv`` under the same configuration hash are
    skipped (resume after a crash or Ctrl-C); ``progress`` is called for those too, first.
    """
    validate(config)
    run_dir.mkdir(parents=True, exist_ok=True)
    store = EpisodeStore(run_dir / EPISODES_CSV, config_hash(config), scene_hash(config))
    for env in sorted(store.done):
        if env < config.episodes and progress is not None:
            progress(env, store.done[env])
    todo = [env for env in range(config.episodes) if env not in store.done]
    if todo:
        context = prepare(config)
    for env in todo:
        log_path = None
        if config.log == "full":
            log_path = run_dir / "logs" / f"episode_{env:03d}.mcap"
        result = run_one(config, context, env, log_path)
        store.append(result)
        if progress is not None:
            progress(env, result)
    results = [store.done[env] for env in range(config.episodes)]
    summary = summarize(results)
    summary.update(
        {
            "task": config.task,
            "method": config.method.name,
            "seed": config.seed,
            "config_hash": store.config_hash,
            "scene_hash": store.scene_hash,
        }
    )
    tmp = run_dir / (SUMMARY_JSON + ".tmp")
    tmp.write_text(json.dumps(summary, indent=2) + "\n")
    os.replace(tmp, run_dir / SUMMARY_JSON)
    return summary
