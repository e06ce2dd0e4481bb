"""The authors' trajectory solver: ``optNewton`` of their framework (``Optim/optimization.cpp``).

Damped Gauss-Newton steps ``Delta = -(H + lambda I)^-1 g`` on the same banded normal equations
as ours (:mod:`~amex.plan.optimizer.linearize`), capped in every joint, with a backtracking line
search; it stops without an update once the step is small (docs/planner.md).
"""

from __future__ import annotations

import math

import numpy as np

from amex.core.errors import SolverError
from amex.plan.optimizer.assembly import (
    CompiledAssembly,
    CompiledSolve,
    Iterate,
    Linearized,
    assembly_for,
)
from amex.plan.optimizer.linearize import Evaluation
from amex.plan.optimizer.numpy_assembly import NumpyAssembly, NumpySolve
from amex.plan.optimizer.residuals import Point, free_knots, initial_guess
from amex.plan.problem import TrajectoryProblem, TrajectorySolution
from amex.robot import RobotModel

__all__ = ["solve_trajectory_newton"]


def _capped_step(
    solve: CompiledSolve | NumpySolve,
    point: Iterate | Point,
    model: Linearized | Evaluation,
    lam: float,
    max_step: float,
    problem: TrajectoryProblem,
) -> tuple[np.ndarray, float]:
    """``Delta = -(H + lambda I)^-1 g``, scaled to at most ``max_step`` per joint; its size."""
    try:  # no pair is ever woken: the band is H + lambda I
        delta = solve.damped_step(point, model, solve.woken(), lam)  # type: ignore[arg-type]
    except SolverError as e:
        raise SolverError(f"Newton Cholesky failed: {e.__cause__}", problem) from e.__cause__
    delta = delta.reshape(point.x.shape)
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
    assembly: CompiledAssembly | NumpyAssembly | None = None,
) -> TrajectorySolution:
    """The authors' Newton method (module notes) from ``q_init`` (default: all knots at the start).

    The line search scales the step by alpha: x0.1 after a rejected trial, square-rooted after
    an accepted one; lambda (from ``damping``, the original's 1e-3) halves after every accepted
    full step. It stops *without an update* when the step is below ``stop_tolerance / 10`` in
    every joint (so most warm-started replans change nothing), and after an update when it was
    below ``stop_tolerance``, after ``max_iterations`` steps or ``max_evaluations`` cost
    evaluations.

    ``assembly``: the iteration's implementation and buffers, as for
    :func:`~amex.plan.optimizer.levenberg.solve_trajectory` (:func:`~.assembly.assembly_for`).

    Returns:
        The trajectory; ``converged`` tells whether a tolerance, not a limit, stopped it.

    Raises:
        SolverError: if the cost is not finite at the start or the factorization fails.
    """
    solve = assembly_for(robot, problem, assembly).begin(problem)
    x = free_knots(robot, problem, initial_guess(problem) if q_init is None else q_init)
    point = solve.evaluate(x)
    current = solve.linearize(point)  # type: ignore[arg-type]
    fx = point.cost
    if not math.isfinite(fx):
        raise SolverError(f"non-finite trajectory cost {fx} at the initial guess", problem)
    lam, alpha, evaluations, iterations, converged = damping, 1.0, 1, 0, False
    while True:
        iterations += 1
        delta, size = _capped_step(solve, point, current, lam, max_step, problem)
        if lam < 2.0 and size < 0.1 * stop_tolerance:  # the lazy stop: no update
            converged = True
            break
        while True:  # line search
            trial = x + alpha * delta
            trial_point = solve.evaluate(trial)
            evaluations += 1
            if math.isfinite(trial_point.cost) and trial_point.cost <= fx:
                x, fx, point = trial, trial_point.cost, trial_point
                current = solve.linearize(point)  # type: ignore[arg-type]
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
