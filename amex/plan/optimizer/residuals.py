"""The trajectory cost ``f(x) = ||r(x)||^2`` at the free knots, and its residuals r.

``r`` stacks the acceleration residuals ``sqrt(w_acc dt) (q_{t+1} - 2 q_t + q_{t-1}) / dt^2``,
the four final terms (:mod:`~amex.plan.optimizer.final_terms`) and the collision term: ours,
``sqrt(w_col) max(0, 1 - d / margin)`` per knot, capsule and obstacle, or the authors' proxy
``sqrt(w_col) sum_p d1_p d2_p`` per knot (``collision_cost``; :mod:`~amex.plan.optimizer.proxy`);
docs/planner.md gives f(x) and its derivation.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.core.errors import SolverError
from amex.plan.batch_kinematics import BatchPoses, CapsuleDistances, batch_kinematics
from amex.plan.kinematics_kernels import near_pairs
from amex.plan.optimizer.assembly_kernels import equal
from amex.plan.optimizer.final_terms import final_terms
from amex.plan.optimizer.proxy import ProxyTerms, proxy_terms
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.robot import RobotModel

__all__ = [
    "GUARD",
    "KnotFrames",
    "Point",
    "acceleration_scale",
    "free_knots",
    "initial_guess",
    "residuals",
    "trajectory_residuals",
]

#: Pairs within ``(1 + GUARD)`` margins may add curvature (:func:`~.levenberg.solve_trajectory`).
GUARD = 0.25


class KnotFrames(NamedTuple):
    """The frames at a trajectory's free knots, and its capsule distances to the obstacles.

    A solution carries those of its final knots (:attr:`TrajectorySolution.frames`); a warm
    start that reuses whole knots of it (CR's shift by one knot) can pass them on, reordered with
    :meth:`take`, instead of computing them again: each knot's frames and distances depend on
    that knot alone, so they are the same numbers.

    Attributes:
        poses: batched frames, one column per free knot.
        dist: distances to ``obstacles`` (None: not computed).
        obstacles: the sphere centres they were computed for, shape (k, 3) [m].
        radii: their radii, shape (k,) [m].
    """

    poses: BatchPoses
    dist: CapsuleDistances | None
    obstacles: np.ndarray
    radii: np.ndarray

    def take(self, columns: np.ndarray | slice) -> KnotFrames:
        """The frames of the free knots ``columns`` (indices into these), in that order.

        A slice gives views (CR's shift by whole knots: nothing copied), indices copies.
        """
        rotation = self.poses.rotation[..., columns]
        poses = BatchPoses(rotation, self.poses.position[..., columns], rotation[:, 2])
        dist = None
        if self.dist is not None:
            d = self.dist
            dist = CapsuleDistances(d.distance[..., columns], d.offset[..., columns])
        return KnotFrames(poses, dist, self.obstacles, self.radii)

    def distances(self, problem: TrajectoryProblem) -> CapsuleDistances | None:
        """The distances, if computed for the obstacles of ``problem``."""
        return self.dist if self.computed_for(problem.obstacles, problem.obstacle_radii) else None

    def computed_for(self, obstacles: np.ndarray, radii: np.ndarray) -> bool:
        """Whether :attr:`dist` was computed for ``obstacles`` and ``radii``.

        ``np.array_equal``'s answer (entry by entry; -0.0 equals 0.0), from one compiled call
        per array (CR's every step asks).
        """
        a, r = self.obstacles, self.radii
        if a.shape != obstacles.shape or r.shape != radii.shape:
            return False
        return bool(equal(a, obstacles) and equal(r, radii))


class Point(NamedTuple):
    """The residuals at the free knots ``x`` and what their derivatives reuse.

    Attributes:
        x: free knots, shape (T, n) [rad].
        residuals: acceleration (T, n), final (m,), collision (C, k, T) (zeros when inactive;
            ``proxy``: one per knot, (T,)).
        cost: f(x).
        final_jacobian: Jacobian of the final residuals, columns (q_{T-1}, q_T) or q_T alone.
        poses: batched joint frames (None without collision term).
        dist: capsule-obstacle distances (None without collision term).
        near: pairs within ``1 + GUARD`` margins, (capsule, obstacle, knot) sorted by knot
            (``proxy``: within the margin).
        proxy: the proxy's terms (``collision_cost=proxy`` with pairs in the margin, else None).
    """

    x: np.ndarray
    residuals: list[np.ndarray]
    cost: float
    final_jacobian: np.ndarray
    poses: BatchPoses | None
    dist: CapsuleDistances | None
    near: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    proxy: ProxyTerms | None = None


def acceleration_scale(costs: TrajectoryCosts, dt: float) -> float | np.ndarray:
    """Factor of the second differences in the acceleration residuals.

    ``sqrt(w dt) / dt^2``, times ``sqrt(H_jj)`` per joint with a joint metric (then shape (n,)).
    """
    s_acc = math.sqrt(costs.weights.acceleration * dt) / dt**2
    if costs.metric:
        return s_acc * np.sqrt(np.asarray(costs.metric, dtype=float))
    return s_acc


def residuals(
    robot: RobotModel,
    data: pin.Data,
    problem: TrajectoryProblem,
    x: np.ndarray,
    known: KnotFrames | None = None,
) -> Point:
    """Residuals and cost at the free knots ``x`` (T, n) [rad], without the normal equations.

    A trial step needs only its cost (and its collision residuals), so the derivatives are left
    to :func:`~amex.plan.optimizer.linearize.linearize`, which is skipped for rejected and final
    steps. ``known``: the frames (and distances) at ``x``, already computed (:class:`KnotFrames`).
    """
    T, n = x.shape
    c, dt = problem.costs, problem.dt
    s_acc = acceleration_scale(c, dt)
    r_acc = np.empty((T, n))
    np.subtract(x[1:], x[:-1], out=r_acc[1:])  # first differences, then second ones
    r_acc[0] = x[0] - problem.q_start
    r_acc[1:] -= r_acc[:-1].copy()
    r_acc[0] -= dt * problem.v_start
    r_acc *= s_acc
    q_prev = x[-2] if T > 1 else problem.q_start
    r_fin, J_fin = final_terms(robot.model, data, robot.tcp_frame_id, problem, q_prev, x[-1])
    if T == 1:  # q_{T-1} is the fixed start
        J_fin = J_fin[:, n:]
    flat_acc = r_acc.ravel()
    cost = float(flat_acc @ flat_acc + r_fin @ r_fin)

    proxy = c.collision_cost == "proxy"
    r_col = np.zeros(T if proxy else (len(robot.capsules), len(problem.obstacle_radii), T))
    poses = dist = near = terms = None
    if len(problem.obstacle_radii) and robot.capsules and c.weights.collision > 0.0:
        kin, w = batch_kinematics(robot), c.weights
        poses = known.poses if known is not None else kin.forward(x)
        dist = known.distances(problem) if known is not None else None
        if dist is None:
            dist = kin.capsule_distances(poses, problem.obstacles, problem.obstacle_radii)
        if proxy:  # the authors' per knot (module notes)
            margin, radii = float(w.collision_margin), problem.obstacle_radii
            found = proxy_terms(
                robot, kin, poses, dist, problem.obstacles, radii, margin, w.collision
            )
            if found.d1.size:
                near, terms, r_col = found.pairs, found, found.residual
                cost += float(r_col @ r_col)
        else:  # the pairs with 1 - d / margin > -GUARD, sorted by knot, and their residuals
            cap, obs, knot, r_near = near_pairs(
                dist.distance, float(w.collision_margin), GUARD, math.sqrt(w.collision), r_col
            )
            if knot.size:
                near = (cap, obs, knot)
                cost += float(r_near @ r_near)
    return Point(x, [r_acc, r_fin, r_col], cost, J_fin, poses, dist, near, terms)


def free_knots(robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray) -> np.ndarray:
    """The free knots ``q[1:]`` of a trajectory of shape (T + 1, n) [rad] (SolverError if not)."""
    q = np.asarray(q, dtype=float)
    shape = (problem.steps + 1, robot.model.nq)
    if q.shape != shape:
        raise SolverError(f"trajectory of shape {q.shape}; expected {shape}", problem)
    return q[1:]


def initial_guess(problem: TrajectoryProblem) -> np.ndarray:
    """All knots at the start (the first Gauss-Newton step is then a min-acceleration reach)."""
    return np.tile(problem.q_start, (problem.steps + 1, 1))


def trajectory_residuals(
    robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray
) -> np.ndarray:
    """The stacked residual vector r with ``cost = r . r``, for inspection and tests (pure).

    Order: acceleration (T x n, knot-major), final position (3), final joint velocity (n), final
    axis (3), final axis rate (3), collision (capsules x obstacles x T, zeros when inactive;
    ``proxy``: T).
    """
    x = free_knots(robot, problem, q)
    point = residuals(robot, robot.model.createData(), problem, x)
    return np.concatenate([r.ravel() for r in point.residuals])
