"""Compute the reference plan once per configuration and keep it on disk.

The cache key is a SHA-256 of everything the plan depends on: the robot (its cleaned
description, :attr:`~amex.robot.RobotModel.fingerprint`), the start
configuration, the goal, the plan settings and :data:`PLAN_FORMAT` (bumped when the optimizer's
mathematics change). Files are written atomically, so parallel workers can share the cache.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from amex.paths import cache_dir
from amex.plan.optimizer import (
    TrajectoryCosts,
    TrajectoryProblem,
    solve_trajectory,
    solve_trajectory_newton,
)
from amex.plan.problem import joint_metric
from amex.plan.reference import PlanConfig, ReferencePlan
from amex.robot import RobotModel

PLAN_FORMAT = 1


def plan_key(robot: RobotModel, config: PlanConfig, goal_pos, goal_axis) -> str:
    """Hex digest identifying the plan for this robot, start, goal and settings."""
    h = hashlib.sha256()
    spec = {
        "format": PLAN_FORMAT,
        "robot": robot.fingerprint,
        "q0": [float(x) for x in robot.q0],
        "goal_pos": [float(x) for x in goal_pos],
        "goal_axis": [float(x) for x in goal_axis],
        "plan": {k: getattr(config, k) for k in sorted(vars(config))},
    }
    h.update(json.dumps(spec, sort_keys=True).encode())
    return h.hexdigest()[:20]


def solve_reference(
    robot: RobotModel, config: PlanConfig, goal_pos: np.ndarray, goal_axis: np.ndarray
) -> ReferencePlan:
    """Solve the reference problem (no obstacles, start at rest in ``robot.q0``) from scratch."""
    metric = joint_metric(config.metric, robot.nv)
    costs = TrajectoryCosts(
        **config.cost_weights(),
        collision=0.0,
        metric=metric,
        final_velocity_space=config.final_velocity_space,
    )
    problem = TrajectoryProblem(
        q_start=robot.q0.copy(),
        v_start=np.zeros(robot.nv),
        steps=config.steps,
        dt=config.dt,
        goal_pos=np.asarray(goal_pos, dtype=float),
        goal_axis=np.asarray(goal_axis, dtype=float),
        obstacles=np.zeros((0, 3)),
        obstacle_radii=np.zeros(0),
        costs=costs,
    )
    if config.solver == "newton":
        solution = solve_trajectory_newton(robot, problem, max_iterations=config.max_iterations)
    else:
        solution = solve_trajectory(robot, problem, max_iterations=config.max_iterations)
    y = np.array([robot.task_position(q) for q in solution.q])
    return ReferencePlan(q=solution.q, y=y, dt=config.dt, metric=metric)


def reference_plan(
    robot: RobotModel,
    config: PlanConfig,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    directory: Path | None = None,
) -> ReferencePlan:
    """The reference plan, from the disk cache when present, else solved and stored."""
    directory = cache_dir() / "plans" if directory is None else directory
    path = directory / f"plan_{plan_key(robot, config, goal_pos, goal_axis)}.npz"
    if path.exists():
        try:
            with np.load(path) as f:
                metric = joint_metric(config.metric, robot.nv)
                return ReferencePlan(q=f["q"], y=f["y"], dt=float(f["dt"]), metric=metric)
        except (OSError, ValueError, KeyError):
            pass  # unreadable (e.g. truncated by a crash): recompute and overwrite
    plan = solve_reference(robot, config, goal_pos, goal_axis)
    directory.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=directory, suffix=".npz")
    with os.fdopen(fd, "wb") as f:
        np.savez(f, q=plan.q, y=plan.y, dt=plan.dt)
    os.replace(tmp, path)
    return plan
