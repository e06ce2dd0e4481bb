"""The numpy iteration of the Levenberg solver: the oracle of the compiled one, and the proxy's.

:func:`~amex.plan.optimizer.residuals.residuals`, :func:`~amex.plan.optimizer.linearize.linearize`
and the damped step below, behind the interface of
:class:`~amex.plan.optimizer.assembly.CompiledSolve` (``begin``, ``evaluate``, ``linearize``,
``damped_step``, ``advance``, ``wake``, ``frames``). The authors' proxy collision term runs
here; ``tests/plan/test_assembly.py`` checks the compiled iteration against it, bit for bit.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import LinAlgError

from amex.core.errors import SolverError
from amex.plan.optimizer.band import band_memory, solve_band
from amex.plan.optimizer.linearize import Evaluation, linearize
from amex.plan.optimizer.residuals import KnotFrames, Point, residuals
from amex.plan.problem import TrajectoryProblem
from amex.robot import RobotModel

__all__ = ["NumpyAssembly", "NumpySolve", "damped_band_numpy", "damped_step", "wake_pushed_in"]


def damped_band_numpy(current: Evaluation, woken: np.ndarray, lam: float) -> np.ndarray:
    """``H + G + lambda I`` in lower band storage, G the curvature of the woken inactive pairs."""
    band = np.array(current.equations.hessian)
    guard = current.guard
    if guard is not None:
        guarded = woken[guard.pairs] & (current.residuals[2][guard.pairs] == 0.0)
        if guarded.any():
            band_memory(band)[guard.flat] += guard.curvature(guarded)
    band[0] += lam
    return band


def damped_step(
    current: Evaluation, woken: np.ndarray, lam: float, problem: TrajectoryProblem
) -> np.ndarray:
    """``dx`` of ``(H + G + lambda I) dx = -g`` (:func:`damped_band_numpy`)."""
    band = damped_band_numpy(current, woken, lam)
    try:
        return solve_band(band, -current.equations.gradient)
    except (LinAlgError, ValueError) as e:
        raise SolverError(f"Gauss-Newton Cholesky failed: {e}", problem) from e


def wake_pushed_in(current: Evaluation, trial: Point, woken: np.ndarray) -> bool:
    """Wake the guard pairs inactive at ``current`` that ``trial`` made active; whether any."""
    guard = current.guard
    if guard is None:
        return False
    newly = trial.residuals[2][guard.pairs] > 0.0
    newly &= current.residuals[2][guard.pairs] == 0.0
    newly &= ~woken[guard.pairs]
    woken[tuple(index[newly] for index in guard.pairs)] = True
    return bool(newly.any())


class NumpyAssembly:
    """The numpy iteration of one robot (module notes)."""

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot

    def begin(self, problem: TrajectoryProblem) -> NumpySolve:
        """The solve of ``problem``."""
        return NumpySolve(self.robot, problem)


class NumpySolve:
    """The numpy iteration of one problem (module notes); points are :class:`~.residuals.Point`."""

    def __init__(self, robot: RobotModel, problem: TrajectoryProblem) -> None:
        self.robot, self.problem = robot, problem
        self.data = robot.model.createData()

    def woken(self) -> np.ndarray:
        """No pair woken yet (flags shaped as the collision residuals)."""
        proxy = self.problem.costs.collision_cost == "proxy"
        k, T = len(self.problem.obstacle_radii), self.problem.steps
        return np.zeros(T if proxy else (len(self.robot.capsules), k, T), dtype=bool)

    def evaluate(self, x: np.ndarray, known: KnotFrames | None = None) -> Point:
        """:func:`~.residuals.residuals` at the free knots ``x``."""
        return residuals(self.robot, self.data, self.problem, x, known)

    def linearize(self, point: Point) -> Evaluation:
        """:func:`~.linearize.linearize` at ``point``."""
        return linearize(self.robot, self.problem, point)

    def damped_step(
        self, point: Point, model: Evaluation, woken: np.ndarray, lam: float
    ) -> np.ndarray:
        """:func:`damped_step`."""
        return damped_step(model, woken, lam, self.problem)

    def step(self, point: Point, step: np.ndarray, tolerance: float) -> tuple[Point, bool]:
        """The point at ``point.x + step`` and whether ``max |step| < tolerance`` [rad]."""
        step = step.reshape(point.x.shape)
        return self.evaluate(point.x + step), float(np.max(np.abs(step))) < tolerance

    def wake(self, point: Point, trial: Point, woken: np.ndarray, model: Evaluation) -> bool:
        """:func:`wake_pushed_in`."""
        return wake_pushed_in(model, trial, woken)

    def frames(self, point: Point) -> KnotFrames | None:
        """The frames and distances at ``point``'s knots (None without collision term)."""
        if point.poses is None:
            return None
        problem = self.problem
        return KnotFrames(point.poses, point.dist, problem.obstacles, problem.obstacle_radii)
