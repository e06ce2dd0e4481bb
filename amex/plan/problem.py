"""What a trajectory optimization is asked and what it returns: costs, problem, solution.

The cost terms are defined in :mod:`amex.plan.optimizer` (its module docstring gives f(x));
these containers validate their inputs once, at construction, so the solver's inner loop does
not have to: a bad shape, range or non-finite value raises here, carrying the problem.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np

from amex.core.errors import ConfigError, SolverError

VELOCITY_SPACES = ("joint", "tcp")


@dataclass(frozen=True)
class TrajectoryCosts:
    """Weights of the cost terms (module docstring); the original's values (DESIGN.md).

    Attributes:
        acceleration: weight of sum_t ||q_ddot_t||^2 dt [s^3/rad^2 per unit cost].
        final_position: weight of the squared TCP position error at q_T [1/m^2].
        final_velocity: weight of the squared joint speed at the end [s^2/rad^2].
        final_axis: weight of the squared TCP z-axis error at q_T.
        final_axis_velocity: weight of the squared TCP z-axis rate at the end [s^2].
        collision: weight of sum over knots and pairs of max(0, 1 - d / margin)^2.
        collision_margin: distance below which the collision term acts [m].
        metric: joint metric diag(H) of the acceleration term, ``sum_t q_ddot_t^T H q_ddot_t dt``
            (:func:`~amex.robot.geometry.joint_metric`); empty: the identity.
        final_velocity_space: the final velocity term on the joints (``joint``, ours:
            ``(q_T - q_{T-1}) / dt``) or on the TCP position (``tcp``, the original's:
            ``(p(q_T) - p(q_{T-1})) / dt``).
    """

    acceleration: float = 1.0
    final_position: float = 1e4
    final_velocity: float = 1e3
    final_axis: float = 1e4
    final_axis_velocity: float = 1e3
    collision: float = 1.0
    collision_margin: float = 0.02  # [m]
    metric: tuple[float, ...] = ()
    final_velocity_space: str = "joint"

    def __post_init__(self) -> None:
        if self.final_velocity_space not in VELOCITY_SPACES:
            raise ConfigError.invalid(
                "final_velocity_space", self.final_velocity_space, VELOCITY_SPACES
            )
        object.__setattr__(self, "metric", tuple(float(h) for h in self.metric))
        if not all(math.isfinite(h) and h > 0.0 for h in self.metric):
            raise ConfigError.invalid("costs.metric", self.metric, "finite weights > 0")
        not_weights = ("collision_margin", "metric", "final_velocity_space")
        weights = (f.name for f in fields(self) if f.name not in not_weights)
        for name in weights:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError.invalid(f"costs.{name}", value, "a finite weight >= 0")
        if not (math.isfinite(self.collision_margin) and self.collision_margin > 0.0):
            raise ConfigError.invalid("costs.collision_margin", self.collision_margin, "> 0 [m]")


@dataclass(frozen=True, eq=False)
class TrajectoryProblem:
    """One trajectory optimization: start state, horizon, goal, obstacles and costs.

    Arrays are copied to float arrays at construction; bad shapes, ranges or non-finite values
    raise :class:`SolverError` carrying the problem.

    Attributes:
        q_start: measured joint position at the horizon start, shape (7,) [rad].
        v_start: measured joint velocity, shape (7,) [rad/s]; defines q_-1 = q_start - dt v_start.
        steps: T, the number of free knots q_1..q_T.
        dt: knot spacing [s].
        goal_pos: TCP goal position in the world frame, shape (3,) [m].
        goal_axis: TCP goal z-axis in the world frame (unit), shape (3,).
        obstacles: sphere centres, shape (k, 3) [m]; k may be 0.
        obstacle_radii: sphere radii, shape (k,) [m].
        costs: weights of the cost terms.
    """

    q_start: np.ndarray
    v_start: np.ndarray
    steps: int
    dt: float
    goal_pos: np.ndarray
    goal_axis: np.ndarray
    obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    obstacle_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    costs: TrajectoryCosts = field(default_factory=TrajectoryCosts)

    def __post_init__(self) -> None:
        names = ("q_start", "v_start", "goal_pos", "goal_axis", "obstacles", "obstacle_radii")
        for name in names:
            object.__setattr__(self, name, np.array(getattr(self, name), dtype=float))
        if self.obstacles.size == 0:
            object.__setattr__(self, "obstacles", np.zeros((0, 3)))
        n, k = max(self.q_start.size, 1), self.obstacle_radii.size
        shapes = ((n,), (n,), (3,), (3,), (k, 3), (k,))
        values = [getattr(self, name) for name in names]
        for name, shape, value in zip(names, shapes, values, strict=True):
            if value.shape != shape:
                raise SolverError(f"trajectory problem: {name} has shape {value.shape}", self)
        if not np.isfinite(np.concatenate([v.ravel() for v in values])).all():  # one check: CR
            for name, value in zip(names, values, strict=True):  # builds one problem per step
                if not np.isfinite(value).all():
                    raise SolverError(f"trajectory problem: non-finite {name}={value}", self)
        if int(self.steps) != self.steps or self.steps < 1:
            raise SolverError(f"trajectory problem: steps={self.steps}; valid: integer >= 1", self)
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise SolverError(f"trajectory problem: dt={self.dt}; valid: > 0 [s]", self)


class TrajectorySolution(NamedTuple):
    """Result of :func:`solve_trajectory`.

    Attributes:
        q: knots including the start as row 0, shape (T + 1, 7) [rad].
        cost: f at ``q``.
        iterations: iterations used (one banded solve and one cost evaluation each, whether the
            step was taken or not).
        converged: whether the step or the relative cost decrease fell below the tolerance.
        frames: the frames and obstacle distances at the free knots ``q[1:]``
            (:class:`amex.plan.optimizer.KnotFrames`), or None (no collision term).
    """

    q: np.ndarray
    cost: float
    iterations: int
    converged: bool
    frames: Any = None
