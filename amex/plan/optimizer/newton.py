"""The authors' trajectory solver: ``optNewton`` of their framework (``Optim/optimization.cpp``).

Damped Gauss-Newton steps ``Delta = -(H + lambda I)^-1 g`` on the same banded normal equations
as ours (:mod:`~amex.plan.optimizer.linearize`), capped in every joint, with a backtracking line
search; it stops without an update once the step is small (docs/planner.md).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import LinAlgError

from amex.core.errors import SolverError
from amex.plan.optimizer.band import solve_band
from amex.plan.optimizer.linearize import Evaluation, evaluate, linearize
from amex.plan.optimizer.residuals import free_knots, initial_guess, residuals
from amex.plan.problem import TrajectoryProblem, TrajectorySolution
from amex.robot import RobotModel

__all__ = ["solve_trajectory_newton"]


def _capped_step(
    current: Evaluation,
    lam: float,
    max_step: float,
    shape: tuple[int, ...],
    problem: TrajectoryProblem,
) -> tuple[np.ndarray, float]:
    """``Delta = -(H + lambda I)^-1 g``, scaled to at most ``max_step`` per joint; its size."""
    band = np.array(current.equations.hessian)
    band[0] += lam
    try:
        delta = solve_band(band, -current.equations.gradient)  # solveh_banded's dpbsv, directly
    except (LinAlgError, ValueError) as e:
        raise SolverError(f"Newton Cholesky failed: {e}", problem) from e
    delta = delta.reshape(shape)
    size = float(np.max(np.abs(delta)))
    if max_step > 0.0 and size > max_step:
        delta *= max_step / size
        size = max_step
    return delta, size


def solve_trajectory_newton(
    robot: RobotModel,
    problem: TrajectoryProblem,
    q_init: np.ndarray | None = None,
    max_iterations: int = 20,
    damping: float = 1e-3,
    max_step: float = 1.0,
    stop_tolerance: float = 1e-2,
    max_evaluations: int = 1000,
) -> TrajectorySolution:
    """The authors' Newton method (module notes) from ``q_init`` (default: all knots at the start).

    The line search scales the step by alpha: x0.1 after a rejected trial, square-rooted after
    an accepted one; lambda (from ``damping``, the original's 1e-3) halves after every accepted
    full step. It stops *without an update* when the step is below ``stop_tolerance / 10`` in
    every joint (so most warm-started replans change nothing), and after an update when it was
    below ``stop_tolerance``, after ``max_iterations`` steps or ``max_evaluations`` cost
    evaluations.

    Returns:
        The trajectory; ``converged`` tells whether a tolerance, not a limit, stopped it.

    Raises:
        SolverError: if the cost is not finite at the start or the factorization fails.
    """
    data = robot.model.createData()
    x = free_knots(robot, problem, initial_guess(problem) if q_init is None else q_init)
    current = evaluate(robot, data, problem, x)
    fx = current.equations.cost
    if not math.isfinite(fx):
        raise SolverError(f"non-finite trajectory cost {fx} at the initial guess", problem)
    lam, alpha, evaluations, iterations, converged = damping, 1.0, 1, 0, False
    while True:
        iterations += 1
        delta, size = _capped_step(current, lam, max_step, x.shape, problem)
        if lam < 2.0 and size < 0.1 * stop_tolerance:  # the lazy stop: no update
            converged = True
            break
        while True:  # line search
            trial = x + alpha * delta
            point = residuals(robot, data, problem, trial)
            evaluations += 1
            if math.isfinite(point.cost) and point.cost <= fx:
                x, fx = trial, point.cost
                current = linearize(robot, problem, point)
                if alpha > 0.9:
                    lam *= 0.5
                alpha = math.sqrt(alpha)
                break
            if alpha * size < 1e-3 * stop_tolerance or evaluations > max_evaluations:
                break
            alpha *= 0.1
        if lam < 2.0 and (size < stop_tolerance or alpha * size < 1e-3 * stop_tolerance):
            converged = True
            break
        if evaluations >= max_evaluations or iterations >= max_iterations:
            break
    return TrajectorySolution(np.vstack([problem.q_start, x]), fx, iterations, converged)
