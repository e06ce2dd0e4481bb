"""Compute the reference plan once per configuration and keep it on disk.

The cache key is a SHA-256 of everything the plan depends on: the robot (its cleaned
description, :attr:`~amex.robot.RobotModel.fingerprint`), the start
configuration, the goal, the plan settings and :data:`PLAN_FORMAT` (bumped when the optimizer's
mathematics change). Files are written atomically (:func:`amex.core.durable.replace_durably`), so
parallel workers can share the cache. A cached file is used only if it holds a finite plan of the
configured shape, sample period and start; a truncated, garbled or mismatched file is solved
again and replaced. A cache that cannot be written (read-only, or its path is a file) costs one
warning and a solve per run, never the run.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import math
from pathlib import Path

import numpy as np

from amex.core.durable import replace_durably
from amex.core.errors import WriteError
from amex.core.paths import cache_dir
from amex.plan.optimizer import (
    TrajectoryCosts,
    TrajectoryProblem,
    solve_trajectory,
    solve_trajectory_newton,
)
from amex.plan.reference import PlanConfig, ReferencePlan
from amex.robot import RobotModel
from amex.robot.geometry import joint_metric

PLAN_FORMAT = 1

log = logging.getLogger(__name__)


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


def reference_costs(robot: RobotModel, config: PlanConfig) -> TrajectoryCosts:
    """The reference problem's cost terms (ConfigError for a setting they cannot take)."""
    metric = joint_metric(config.metric, robot.nv)
    return TrajectoryCosts.from_weights(config, metric, config.final_velocity_space)


def solve_reference(
    robot: RobotModel, config: PlanConfig, goal_pos: np.ndarray, goal_axis: np.ndarray
) -> ReferencePlan:
    """Solve the reference problem (no obstacles, start at rest in ``robot.q0``) from scratch."""
    costs = reference_costs(robot, config)
    metric = costs.metric
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


def load_cached(path: Path, robot: RobotModel, config: PlanConfig) -> ReferencePlan | None:
    """The plan stored at ``path`` if it is readable and fits ``config`` and ``robot``, else None.

    Fits: ``q`` of shape (steps + 1, nv) starting at ``robot.q0``, ``y`` of shape (steps + 1, 6),
    the configured ``dt`` (so also the duration), every value finite.
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            q = np.array(f["q"], dtype=float)
            y = np.array(f["y"], dtype=float)
            dt = float(f["dt"])
    except Exception:  # missing, truncated, garbled, not an npz: numpy raises many types
        return None
    n = config.steps + 1
    fits = (
        q.shape == (n, robot.nv)
        and y.shape == (n, 6)
        and math.isclose(dt, config.dt, rel_tol=1e-12)
        and bool(np.isfinite(q).all() and np.isfinite(y).all())
        and np.allclose(q[0], robot.q0, rtol=0.0, atol=1e-9)
    )
    if not fits:
        return None
    return ReferencePlan(q=q, y=y, dt=config.dt, metric=joint_metric(config.metric, robot.nv))


def store(path: Path, plan: ReferencePlan) -> bool:
    """Write ``plan`` to ``path`` atomically; False (and one warning) if the cache is unwritable."""
    buffer = io.BytesIO()
    np.savez(buffer, q=plan.q, y=plan.y, dt=plan.dt)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        replace_durably(path, buffer.getvalue())
    except (OSError, WriteError) as e:
        reason = e.reason if isinstance(e, WriteError) else (e.strerror or str(e))
        log.warning(
            "plan cache %s not written (%s): the plan is solved again by every run; "
            "set AMEX_CACHE_DIR to a writable directory",
            path.parent,
            reason,
        )
        return False
    return True


def reference_plan(
    robot: RobotModel,
    config: PlanConfig,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    directory: Path | None = None,
) -> ReferencePlan:
    """The reference plan: from the disk cache when a fitting one is there, else solved, stored."""
    directory = cache_dir() / "plans" if directory is None else directory
    path = directory / f"plan_{plan_key(robot, config, goal_pos, goal_axis)}.npz"
    plan = load_cached(path, robot, config)
    if plan is None:
        plan = solve_reference(robot, config, goal_pos, goal_axis)
        store(path, plan)
    return plan
