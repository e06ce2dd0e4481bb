"""What a trajectory optimization is asked and what it returns: costs, problem, solution.

The cost f(x) is in docs/planner.md. These containers validate their inputs once, at
construction, so the solver's inner loop does not have to: a bad shape, range or non-finite
value raises here, carrying the problem.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numpy as np

from amex.core.compiled import kernel
from amex.core.errors import ConfigError, SolverError
from amex.plan.weights import CollisionWeights, CostWeights

VELOCITY_SPACES = ("joint", "tcp")
#: Forms of the collision term: ours per pair, the authors' per knot (:mod:`.optimizer.proxy`).
COLLISION_COSTS = ("hinge", "proxy")


@dataclass(frozen=True)
class TrajectoryCosts:
    """The cost terms of a trajectory optimization: their weights, the joint metric, the velocity.

    Attributes:
        weights: the weights of the terms (copied at construction, so a configuration changed
            later does not change them).
        metric: joint metric diag(H) of the acceleration term, ``sum_t q_ddot_t^T H q_ddot_t dt``
            (:func:`~amex.robot.geometry.joint_metric`); empty: the identity.
        final_velocity_space: the final velocity term on the joints (``joint``, ours:
            ``(q_T - q_{T-1}) / dt``) or on the TCP position (``tcp``, the original's:
            ``(p(q_T) - p(q_{T-1})) / dt``).
        collision_cost: the collision term per knot, pair and obstacle, ``max(0, 1 - d / m)^2``
            (``hinge``, ours), or per knot, the authors' ``(sum_p d1_p d2_p)^2`` (``proxy``,
            :mod:`~amex.plan.optimizer.proxy`).
    """

    weights: CollisionWeights = field(default_factory=CollisionWeights)
    metric: tuple[float, ...] = ()
    final_velocity_space: str = "joint"
    collision_cost: str = "hinge"

    @classmethod
    def from_weights(
        cls,
        weights: CostWeights,
        metric: tuple[float, ...] = (),
        final_velocity_space: str = "joint",
        collision_cost: str = "hinge",
    ) -> TrajectoryCosts:
        """The costs with the weights of ``weights``, e.g. a configuration that inherits them.

        Weights without the collision fields (:class:`CostWeights`, the reference plan's) give
        no collision term.
        """
        names = [f.name for f in fields(CollisionWeights) if hasattr(weights, f.name)]
        values = {name: getattr(weights, name) for name in names}
        if not isinstance(weights, CollisionWeights):
            values["collision"] = 0.0
        return cls(CollisionWeights(**values), metric, final_velocity_space, collision_cost)

    def __post_init__(self) -> None:
        if self.final_velocity_space not in VELOCITY_SPACES:
            raise ConfigError.invalid(
                "final_velocity_space", self.final_velocity_space, VELOCITY_SPACES
            )
        if self.collision_cost not in COLLISION_COSTS:
            raise ConfigError.invalid("collision_cost", self.collision_cost, COLLISION_COSTS)
        object.__setattr__(self, "metric", tuple(float(h) for h in self.metric))
        if not all(math.isfinite(h) and h > 0.0 for h in self.metric):
            raise ConfigError.invalid("costs.metric", self.metric, "finite weights > 0")
        w = self.weights
        copy = CollisionWeights(**{f.name: getattr(w, f.name) for f in fields(CollisionWeights)})
        object.__setattr__(self, "weights", copy)
        for name in (f.name for f in fields(copy) if f.name != "collision_margin"):
            value = getattr(copy, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError.invalid(f"costs.{name}", value, "a finite weight >= 0")
        if not (math.isfinite(copy.collision_margin) and copy.collision_margin > 0.0):
            raise ConfigError.invalid("costs.collision_margin", copy.collision_margin, "> 0 [m]")


@dataclass(frozen=True, eq=False, init=False)
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

    def __init__(
        self,
        q_start: np.ndarray,
        v_start: np.ndarray,
        steps: int,
        dt: float,
        goal_pos: np.ndarray,
        goal_axis: np.ndarray,
        obstacles: np.ndarray | None = None,
        obstacle_radii: np.ndarray | None = None,
        costs: TrajectoryCosts | None = None,
    ) -> None:
        # written out, not the dataclass's __init__ and a __post_init__: CR builds one problem
        # per outer step (six copies, six shape checks and one compiled finiteness check)
        setattr_, asfloat = object.__setattr__, np.array
        q, v = asfloat(q_start, dtype=float), asfloat(v_start, dtype=float)
        g, a = asfloat(goal_pos, dtype=float), asfloat(goal_axis, dtype=float)
        o = np.zeros((0, 3)) if obstacles is None else asfloat(obstacles, dtype=float)
        r = np.zeros(0) if obstacle_radii is None else asfloat(obstacle_radii, dtype=float)
        if o.size == 0:
            o = np.zeros((0, 3))
        setattr_(self, "q_start", q)
        setattr_(self, "v_start", v)
        setattr_(self, "steps", steps)
        setattr_(self, "dt", dt)
        setattr_(self, "goal_pos", g)
        setattr_(self, "goal_axis", a)
        setattr_(self, "obstacles", o)
        setattr_(self, "obstacle_radii", r)
        setattr_(self, "costs", TrajectoryCosts() if costs is None else costs)
        n, k = max(q.size, 1), r.size
        shapes = ((n,), (n,), (3,), (3,), (k, 3), (k,))
        if (q.shape, v.shape, g.shape, a.shape, o.shape, r.shape) != shapes:
            for name, shape, value in zip(_ARRAYS, shapes, (q, v, g, a, o, r), strict=True):
                if value.shape != shape:
                    raise SolverError(f"trajectory problem: {name} has shape {value.shape}", self)
        if not kernel("amex.plan.problem_kernels", "all_finite")(q, v, g, a, o, r):  # compiled
            for name, value in zip(_ARRAYS, (q, v, g, a, o, r), strict=True):
                if not np.isfinite(value).all():
                    raise SolverError(f"trajectory problem: non-finite {name}={value}", self)
        if int(steps) != steps or steps < 1:
            raise SolverError(f"trajectory problem: steps={steps}; valid: integer >= 1", self)
        if not (math.isfinite(dt) and dt > 0.0):
            raise SolverError(f"trajectory problem: dt={dt}; valid: > 0 [s]", self)

    @classmethod
    def prechecked(
        cls,
        q_start: np.ndarray,
        v_start: np.ndarray,
        steps: int,
        dt: float,
        goal_pos: np.ndarray,
        goal_axis: np.ndarray,
        obstacles: np.ndarray,
        obstacle_radii: np.ndarray,
        costs: TrajectoryCosts,
    ) -> TrajectoryProblem:
        """The same problem, its arrays kept as given: no copies, no checks.

        For a caller whose arrays are float64 of the problem's shapes (obstacles (k, 3), also
        for k = 0), finite, never written afterwards, and whose ``steps`` and ``dt`` are valid:
        CR's step, whose arrays are an :class:`~amex.core.types.Observation`'s (finite by
        construction, new at every outer step, obstacles replaced rather than moved in place)
        and whose horizon it computed itself.
        """
        problem = object.__new__(cls)
        put = object.__setattr__
        put(problem, "q_start", q_start)
        put(problem, "v_start", v_start)
        put(problem, "steps", steps)
        put(problem, "dt", dt)
        put(problem, "goal_pos", goal_pos)
        put(problem, "goal_axis", goal_axis)
        put(problem, "obstacles", obstacles)
        put(problem, "obstacle_radii", obstacle_radii)
        put(problem, "costs", costs)
        return problem

    def check(self) -> None:
        """Run the constructor's checks on this problem (one made :meth:`prechecked` too).

        Raises:
            SolverError: naming the field with a bad shape or a non-finite value.
        """
        TrajectoryProblem(*(getattr(self, f.name) for f in fields(self)))


#: The array fields of :class:`TrajectoryProblem`, in the order of their shape checks.
_ARRAYS = ("q_start", "v_start", "goal_pos", "goal_axis", "obstacles", "obstacle_radii")


class TrajectorySolution(NamedTuple):
    """Result of :func:`solve_trajectory`.

    Attributes:
        q: knots including the start as row 0, shape (T + 1, 7) [rad].
        cost: f at ``q``.
        iterations: iterations used (one banded solve and one cost evaluation each, whether the
            step was taken or not).
        converged: whether the step or the relative cost decrease fell below the tolerance.
        frames: the frames and obstacle distances at the free knots ``q[1:]``
            (:class:`~amex.plan.optimizer.KnotFrames`), or None (no collision term).
    """

    q: np.ndarray
    cost: float
    iterations: int
    converged: bool
    frames: Any = None
