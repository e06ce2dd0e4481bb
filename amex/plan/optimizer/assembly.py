"""One Gauss-Newton iteration's residuals, normal equations and damped band, compiled.

:class:`CompiledAssembly` is what :func:`~amex.plan.optimizer.levenberg.solve_trajectory` runs
on (CR's every outer step): the kinematics kernels, Pinocchio's final-term kinematics and
LAPACK's banded Cholesky, glued by a few compiled loops (:mod:`.assembly_kernels`) instead of
~60 numpy operations per iteration, with its band buffer and Pinocchio data kept from one solve
to the next. The numbers are those of the numpy functions it replaces (the oracle,
:class:`NumpyAssembly`: :func:`~.residuals.residuals`, :func:`~.linearize.linearize`, the damped
step) bit for bit; ``tests/plan/test_assembly.py`` compares them. The authors' proxy collision
term (``collision_cost=proxy``) runs on the oracle.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.linalg import LinAlgError

from amex.core.errors import SolverError
from amex.plan.batch_kinematics import BatchPoses, CapsuleDistances, batch_kinematics
from amex.plan.kinematics_kernels import near_pairs
from amex.plan.optimizer.assembly_kernels import (
    acceleration_residuals,
    damped_band,
    gradient_rhs,
    take_step,
    wake_pairs,
)
from amex.plan.optimizer.band import solve_band
from amex.plan.optimizer.final_terms import final_terms, final_weights
from amex.plan.optimizer.residuals import GUARD, KnotFrames, acceleration_scale
from amex.plan.problem import TrajectoryProblem
from amex.robot import RobotModel

__all__ = ["CompiledAssembly", "CompiledSolve", "Iterate", "Linearized"]

_NO_PAIRS = np.zeros(0, dtype=np.int64)


class Iterate(NamedTuple):
    """The residuals and cost at the free knots ``x`` (T, n) [rad] (as :class:`~.residuals.Point`).

    Attributes:
        x: free knots, shape (T, n) [rad].
        r_acc: acceleration residuals, shape (T, n).
        r_fin: final residuals, shape (m,).
        J_fin: their Jacobian, columns (q_{T-1}, q_T) or q_T alone.
        cost: f(x).
        poses: joint frames (None without collision term).
        dist: capsule-obstacle distances (None without collision term).
        r_col: collision residuals, shape (C, k, T), zeros but at the near pairs.
        cap, obs, knot: the pairs within ``1 + GUARD`` margins, sorted by knot (P,).
        r_near: their residuals, shape (P,).
    """

    x: np.ndarray
    r_acc: np.ndarray
    r_fin: np.ndarray
    J_fin: np.ndarray
    cost: float
    poses: BatchPoses | None
    dist: CapsuleDistances | None
    r_col: np.ndarray
    cap: np.ndarray
    obs: np.ndarray
    knot: np.ndarray
    r_near: np.ndarray


class Linearized(NamedTuple):
    """What the damped steps at an iterate need: ``-2 J^T r`` and the pieces of ``2 J^T J``.

    Attributes:
        rhs: ``-2 J^T r``, shape (nT,).
        final_block: ``2 J_fin^T J_fin``, shape (m, m), from row/column ``final_first``.
        final_first: its first row.
        J_col: the near pairs' collision Jacobian rows, shape (P, n).
    """

    rhs: np.ndarray
    final_block: np.ndarray
    final_first: int
    J_col: np.ndarray


class CompiledAssembly:
    """The compiled iteration of one robot, and the buffers its solves reuse.

    Args:
        robot: the arm.

    One per caller that solves repeatedly (CR holds one); not for concurrent solves.
    """

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot
        self.kinematics = batch_kinematics(robot)
        self.data = robot.model.createData()
        self._band = np.zeros((1, 0), order="F")

    def band(self, width: int, size: int) -> np.ndarray:
        """A Fortran-ordered (width, size) buffer (its entries are overwritten by each use)."""
        buffer = self._band
        if buffer.shape[0] != width or buffer.shape[1] < size:
            buffer = self._band = np.empty((width, size), order="F")
        return buffer[:, :size]

    def begin(self, problem: TrajectoryProblem) -> CompiledSolve:
        """The solve of ``problem`` (its constants worked out once)."""
        return CompiledSolve(self, problem)


class CompiledSolve:
    """The compiled iteration of one problem (:class:`CompiledAssembly`; module notes)."""

    def __init__(self, assembly: CompiledAssembly, problem: TrajectoryProblem) -> None:
        c, dt, n = problem.costs, float(problem.dt), assembly.robot.model.nv
        self.assembly, self.problem, self.n = assembly, problem, n
        s_acc = acceleration_scale(c, dt)
        self.s_acc = np.full(n, s_acc) if isinstance(s_acc, float) else s_acc
        self.s_acc2 = np.full(n, 2.0 * s_acc) if isinstance(s_acc, float) else 2.0 * s_acc
        self.band_scale = 2.0 * float(c.weights.acceleration) / dt**3
        self.metric = np.asarray(c.metric, dtype=float)
        robot, w = assembly.robot, c.weights
        self.collides = bool(len(problem.obstacle_radii) and robot.capsules and w.collision > 0.0)
        self.margin = float(w.collision_margin)
        self.s_col = math.sqrt(w.collision)
        self.shape = (len(robot.capsules), len(problem.obstacle_radii), problem.steps)
        self.final_weights = final_weights(c)

    def woken(self) -> np.ndarray:
        """No pair woken yet: (C, k, T) flags."""
        return np.zeros(self.shape, dtype=bool)

    def evaluate(self, x: np.ndarray, known: KnotFrames | None = None) -> Iterate:
        """Residuals and cost at the free knots ``x`` (T, n) (:func:`~.residuals.residuals`)."""
        problem, robot, T = self.problem, self.assembly.robot, x.shape[0]
        r_acc = np.empty_like(x)
        acceleration_residuals(x, problem.q_start, problem.v_start, problem.dt, self.s_acc, r_acc)
        q_prev = x[-2] if T > 1 else problem.q_start
        data = self.assembly.data
        r_fin, J_fin = final_terms(
            robot.model, data, robot.tcp_frame_id, problem, q_prev, x[-1], self.final_weights
        )
        if T == 1:  # q_{T-1} is the fixed start
            J_fin = J_fin[:, self.n :]
        flat_acc = r_acc.reshape(-1)
        cost = float(flat_acc @ flat_acc + r_fin @ r_fin)
        r_col = np.zeros(self.shape)
        if not self.collides:
            return Iterate(x, r_acc, r_fin, J_fin, cost, None, None, r_col, *_none())
        kin = self.assembly.kinematics
        poses = known.poses if known is not None else kin.forward(x)
        dist = known.distances(problem) if known is not None else None
        if dist is None:
            dist = kin.capsule_distances(poses, problem.obstacles, problem.obstacle_radii)
        cap, obs, knot, r_near = near_pairs(dist.distance, self.margin, GUARD, self.s_col, r_col)
        if knot.size:
            cost += float(r_near @ r_near)
        return Iterate(x, r_acc, r_fin, J_fin, cost, poses, dist, r_col, cap, obs, knot, r_near)

    def linearize(self, point: Iterate) -> Linearized:
        """``-2 J^T r`` and the pieces of ``2 J^T J`` at ``point`` (:func:`~.linearize.linearize`)."""
        J_fin, T = point.J_fin, point.x.shape[0]
        m = J_fin.shape[1]
        final_gradient = 2.0 * (J_fin.T @ point.r_fin)
        final_block = 2.0 * (J_fin.T @ J_fin)
        if point.knot.size and point.poses is not None and point.dist is not None:
            J_col = self.assembly.kinematics.distance_gradients(
                point.poses, point.dist, self.problem.obstacles, (point.cap, point.obs, point.knot)
            )
            J_col *= -self.s_col / self.margin
        else:
            J_col = np.zeros((0, self.n))
        rhs = np.empty(T * self.n)
        gradient_rhs(point.r_acc, self.s_acc2, final_gradient, point.knot, point.r_near, J_col, rhs)
        return Linearized(rhs, final_block, self.n * T - m, J_col)

    def damped_step(
        self, point: Iterate, model: Linearized, woken: np.ndarray, lam: float
    ) -> np.ndarray:
        """``dx`` (nT,) of ``(H + G + lambda I) dx = -g`` (:func:`~.levenberg._damped_step`)."""
        n = self.n
        band = self.assembly.band(2 * n + 1, n * point.x.shape[0])
        damped_band(
            band,
            self.band_scale,
            self.metric,
            model.final_block,
            model.final_first,
            point.cap,
            point.obs,
            point.knot,
            model.J_col,
            point.r_near,
            woken,
            lam,
        )
        try:
            return solve_band(band, model.rhs.copy())
        except (LinAlgError, ValueError) as e:
            raise SolverError(f"Gauss-Newton Cholesky failed: {e}", self.problem) from e

    def advance(self, x: np.ndarray, step: np.ndarray) -> tuple[np.ndarray, float]:
        """``x + step`` and the largest ``|step|`` [rad]."""
        out = np.empty_like(x)
        return out, take_step(x, step, out)

    def wake(self, point: Iterate, trial: Iterate, woken: np.ndarray, model: Linearized) -> bool:
        """Wake the pairs inactive at ``point`` that ``trial`` made active; whether any."""
        if not point.knot.size:
            return False
        return bool(wake_pairs(point.cap, point.obs, point.knot, point.r_near, trial.r_col, woken))

    def frames(self, point: Iterate) -> KnotFrames | None:
        """The frames and distances at ``point``'s knots (None without collision term)."""
        if point.poses is None:
            return None
        problem = self.problem
        return KnotFrames(point.poses, point.dist, problem.obstacles, problem.obstacle_radii)


def _none() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """No near pairs: empty (cap, obs, knot, r_near)."""
    return _NO_PAIRS, _NO_PAIRS, _NO_PAIRS, np.zeros(0)
