"""Gauss-Newton normal equations of the trajectory cost: ``2 J^T J`` (banded) and ``2 J^T r``.

The model ``f(x + dx) ~ f + 2 r^T J dx + dx^T J^T J dx`` of the residuals
(:mod:`~amex.plan.optimizer.residuals`); knot-major ordering makes ``2 J^T J`` a band of
``2n`` subdiagonals (:mod:`~amex.plan.optimizer.band`; docs/planner.md).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.plan.batch_kinematics import batch_kinematics
from amex.plan.optimizer.band import acceleration_band, add_block, band_memory, lower_triangle
from amex.plan.optimizer.proxy import proxy_jacobian
from amex.plan.optimizer.residuals import (
    Point,
    acceleration_scale,
    free_knots,
    residuals,
)
from amex.plan.problem import TrajectoryProblem
from amex.robot import RobotModel

__all__ = [
    "Evaluation",
    "Guard",
    "NormalEquations",
    "build_normal_equations",
    "evaluate",
    "linearize",
]


class NormalEquations(NamedTuple):
    """Gauss-Newton model of f at x, ``f(x + dx) ~ f + gradient . dx + dx^T hessian dx / 2``.

    Attributes:
        hessian: ``2 J^T J`` in LAPACK lower band storage (``solveh_banded(..., lower=True)``),
            ``hessian[i - j, j] = H[i, j]`` for ``0 <= i - j <= 2n``, shape (2n + 1, nT), in
            Fortran order (as LAPACK reads it: no copy before each solve); its entries are
            updated in place through :func:`~.band.band_memory`.
        gradient: ``2 J^T r``, shape (nT,) for knots q_1..q_T stacked knot-major.
        cost: f(x).
    """

    hessian: np.ndarray
    gradient: np.ndarray
    cost: float


class Guard(NamedTuple):
    """Collision pairs within ``1 + GUARD`` margins and their ``2 J^T J`` blocks."""

    pairs: tuple[np.ndarray, np.ndarray, np.ndarray]  # (capsule, obstacle, knot), sorted by knot
    outer: np.ndarray  # (P, n (n + 1) / 2) lower-triangle entries of each pair's 2 J^T J
    first: np.ndarray  # index of each knot's first pair
    flat: np.ndarray  # flat indices of the knots' blocks in the band

    def curvature(self, mask: np.ndarray) -> np.ndarray:
        """Summed blocks of the pairs in ``mask``, aligned with ``flat``."""
        return np.add.reduceat(self.outer * mask[:, None], self.first, axis=0).ravel()


class Evaluation(NamedTuple):
    """The residuals at a point, the normal equations there and the guard's curvature."""

    residuals: list[np.ndarray]  # acceleration (T, n), final (m,), collision (C, k, T)
    equations: NormalEquations
    guard: Guard | None


def linearize(robot: RobotModel, problem: TrajectoryProblem, point: Point) -> Evaluation:
    """Normal equations and guard curvature at ``point`` (see :func:`.residuals.residuals`).

    The guard holds ``2 J^T J`` of each collision pair within ``(1 + GUARD)`` margins;
    :func:`~amex.plan.optimizer.levenberg.solve_trajectory` may add those of inactive pairs to
    the matrix (never to the cost). The authors' proxy (``collision_cost=proxy``) has none.
    """
    T, n = point.x.shape
    c, dt = problem.costs, problem.dt
    r_acc, r_fin, r_col = point.residuals
    s_acc = acceleration_scale(c, dt)
    grad = np.empty((T, n))  # D^T r_acc: r_t - 2 r_{t+1} + r_{t+2}, zero past the end
    grad[:] = r_acc
    grad[:-1] -= 2.0 * r_acc[1:]
    grad[:-2] += r_acc[2:]
    grad *= 2.0 * s_acc
    hessian = np.array(acceleration_band(n, T, float(dt), float(c.weights.acceleration), c.metric))

    J_fin = point.final_jacobian
    m = J_fin.shape[1]
    grad.reshape(-1)[-m:] += 2.0 * (J_fin.T @ r_fin)
    add_block(hessian, 2.0 * (J_fin.T @ J_fin), n * T - m)

    guard = None
    if point.proxy is not None and point.poses is not None and point.dist is not None:
        w = c.weights  # the authors' proxy: one residual per knot, no guard
        rows, J_col = proxy_jacobian(
            batch_kinematics(robot),
            point.poses,
            point.dist,
            problem.obstacles,
            point.proxy,
            float(w.collision_margin),
            w.collision,
        )
        grad[rows] += 2.0 * r_col[rows][:, None] * J_col
        i, j = lower_triangle(n)
        flat = ((rows[:, None] * n + j) * (2 * n + 1) + (i - j)).ravel()  # band_memory's
        band_memory(hessian)[flat] += (2.0 * J_col[:, i] * J_col[:, j]).ravel()
    elif point.near is not None and point.poses is not None and point.dist is not None:
        kin = batch_kinematics(robot)
        cap, obs, knot = near = point.near
        margin = c.weights.collision_margin
        s_col = math.sqrt(c.weights.collision)
        r_near = r_col[near]
        J_col = (-s_col / margin) * kin.distance_gradients(
            point.poses, point.dist, problem.obstacles, near
        )
        first = np.concatenate(([0], np.flatnonzero(knot[1:] != knot[:-1]) + 1))
        rows = knot[first]  # the knots with near pairs, each once
        grad[rows] += np.add.reduceat(2.0 * r_near[:, None] * J_col, first, axis=0)
        i, j = lower_triangle(n)
        outer = 2.0 * J_col[:, i] * J_col[:, j]  # (P, n (n + 1) / 2)
        flat = ((rows[:, None] * n + j) * (2 * n + 1) + (i - j)).ravel()  # band_memory's
        active = (r_near > 0.0)[:, None]
        band_memory(hessian)[flat] += np.add.reduceat(outer * active, first, axis=0).ravel()
        guard = Guard(near, outer, first, flat)
    return Evaluation(
        point.residuals, NormalEquations(hessian, grad.reshape(-1), point.cost), guard
    )


def evaluate(
    robot: RobotModel, data: pin.Data, problem: TrajectoryProblem, x: np.ndarray
) -> Evaluation:
    """Residuals, normal equations and guard curvature at the free knots ``x`` (T, n) [rad]."""
    return linearize(robot, problem, residuals(robot, data, problem, x))


def build_normal_equations(
    robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray
) -> NormalEquations:
    """Gauss-Newton normal equations of ``problem`` at the trajectory ``q`` (pure).

    Args:
        robot: the arm.
        problem: the optimization problem.
        q: trajectory, shape (T + 1, 7) [rad]; row 0 is ignored (the start is ``problem.q_start``).

    Returns:
        The banded ``2 J^T J``, the gradient ``2 J^T r`` and the cost (docs/planner.md).
    """
    x = free_knots(robot, problem, q)
    return evaluate(robot, robot.model.createData(), problem, x).equations
