"""A run: the reference plan, then ``episodes`` environments of one task with one method.

Writes into the run directory ``episodes.csv`` (one row per episode, appended and flushed as each
episode ends) and ``summary.json`` (the aggregates). No Hydra here: :func:`run` takes a validated
:class:`~amex.config.RunConfig` and a directory, so scripts can call it directly.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from amex.config import RunConfig, validate
from amex.episode import run_episode
from amex.methods import get_method
from amex.metrics import COLUMNS, EpisodeResult, summarize
from amex.plan.cache import reference_plan
from amex.plan.reference import ReferencePlan
from amex.robot import RobotModel, load_robot
from amex.scenario import make_scenario

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
    if log_path is None:
        return run_episode(context.robot, method, scenario, config.gains(), config.loop)
    from amex.log import EpisodeLogger

    metadata = {"task": config.task, "method": config.method.name, "env": env, "seed": config.seed}
    with EpisodeLogger(log_path, context.robot, context.plan, scenario, metadata) as logger:
        return run_episode(context.robot, method, scenario, config.gains(), config.loop, logger)


def format_value(value: object) -> str:
    """CSV text of a metric: ``repr`` of floats (round-trips bit for bit), 0/1 for booleans."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def run(
    config: RunConfig,
    run_dir: Path,
    progress: Callable[[int, EpisodeResult], None] | None = None,
) -> dict:
    """Execute the run into ``run_dir``; return the summary (also written as ``summary.json``)."""
    validate(config)
    run_dir.mkdir(parents=True, exist_ok=True)
    context = prepare(config)
    results: list[EpisodeResult] = []
    csv_path = run_dir / EPISODES_CSV
    with open(csv_path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(COLUMNS)
        f.flush()
        for env in range(config.episodes):
            log_path = None
            if config.log == "full":
                log_path = run_dir / "logs" / f"episode_{env:03d}.mcap"
            result = run_one(config, context, env, log_path)
            results.append(result)
            writer.writerow([format_value(v) for v in result.as_row().values()])
            f.flush()
            os.fsync(f.fileno())
            if progress is not None:
                progress(env, result)
    summary = summarize(results)
    summary.update({"task": config.task, "method": config.method.name, "seed": config.seed})
    tmp = run_dir / (SUMMARY_JSON + ".tmp")
    tmp.write_text(json.dumps(summary, indent=2, sort_keys=False) + "\n")
    os.replace(tmp, run_dir / SUMMARY_JSON)
    return summary
