"""Our trajectory solver: Levenberg-damped Gauss-Newton on the banded normal equations.

Each iteration solves ``(2 J^T J + lambda I) dx = -2 J^T r`` (one banded Cholesky) and evaluates
the cost at ``x + dx``; the paper's reference planner ("quadratic cost terms and a Gauss-Newton
optimizer", Section IV) and CR's replanning (Section IV-A). Step rules and measurements:
docs/planner.md.
"""

from __future__ import annotations

import ctypes
import math
from functools import cache

import numpy as np
from scipy.linalg import LinAlgError

from amex.core.errors import ConfigError, SolverError
from amex.plan.optimizer.band import band_memory, solve_band
from amex.plan.optimizer.linearize import Evaluation, linearize
from amex.plan.optimizer.residuals import KnotFrames, Point, free_knots, initial_guess, residuals
from amex.plan.problem import TrajectoryProblem, TrajectorySolution
from amex.robot import RobotModel

__all__ = ["solve_trajectory"]

_INITIAL_DAMPING = 1.0  # Levenberg lambda of the first iteration (see solve_trajectory)
_M_TRIM_THRESHOLD = -1  # glibc mallopt parameter
_TRIM_THRESHOLD = 64 << 20  # [bytes] free heap glibc keeps instead of returning it to the OS


@cache
def _retain_freed_memory() -> bool:
    """Keep glibc from returning freed heap memory to the OS (``mallopt(M_TRIM_THRESHOLD)``).

    An evaluation at 400 knots allocates and frees ~1 MB; with glibc's default trim threshold
    each one page-faults the heap top in again (docs/planner.md). A process-wide setting with no
    effect on results; a no-op (False) where mallopt is missing.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError, TypeError):
        return False
    return bool(mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD))


def _damped_step(
    current: Evaluation, woken: np.ndarray, lam: float, problem: TrajectoryProblem
) -> np.ndarray:
    """``dx`` of ``(H + G + lambda I) dx = -g``, G the curvature of the woken inactive pairs."""
    band = np.array(current.equations.hessian)
    guard = current.guard
    if guard is not None:
        guarded = woken[guard.pairs] & (current.residuals[2][guard.pairs] == 0.0)
        if guarded.any():
            band_memory(band)[guard.flat] += guard.curvature(guarded)
    band[0] += lam
    try:
        return solve_band(band, -current.equations.gradient)
    except (LinAlgError, ValueError) as e:
        raise SolverError(f"Gauss-Newton Cholesky failed: {e}", problem) from e


def _wake_pushed_in(current: Evaluation, trial: Point, woken: np.ndarray) -> bool:
    """Wake the guard pairs inactive at ``current`` that ``trial`` made active; whether any."""
    guard = current.guard
    if guard is None:
        return False
    newly = trial.residuals[2][guard.pairs] > 0.0
    newly &= current.residuals[2][guard.pairs] == 0.0
    newly &= ~woken[guard.pairs]
    woken[tuple(index[newly] for index in guard.pairs)] = True
    return bool(newly.any())


def solve_trajectory(
    robot: RobotModel,
    problem: TrajectoryProblem,
    q_init: np.ndarray | None = None,
    max_iterations: int = 20,
    tolerance: float = 1e-4,
    damping: float = 1e-3,
    init_frames: KnotFrames | None = None,
) -> TrajectorySolution:
    """Minimize the trajectory cost by Levenberg-damped Gauss-Newton.

    A step that does not increase the cost is taken and lambda shrinks 10x (down to
    ``damping``); a rejected step either wakes the guard pairs it pushed into the margin (their
    curvature joins the matrix) or grows lambda 10x. lambda starts at ``max(damping, 1)``. The
    solve stops when an accepted step lowers the cost by less than ``tolerance`` relative, when
    a step is below ``tolerance`` [rad] in every joint, or after ``max_iterations`` iterations.

    Args:
        robot: the arm.
        problem: the optimization problem.
        q_init: initial trajectory, shape (T + 1, 7) [rad] (row 0 is replaced by the start), e.g.
            :func:`~amex.plan.knots.shift_warm_start` of the previous solution; default: all
            knots at the start.
        max_iterations: cap on iterations (solve + evaluation each).
        tolerance: stopping threshold on the relative cost decrease and on the step [rad].
        damping: smallest Levenberg term lambda on the Hessian diagonal (the original: 1e-3).
        init_frames: the frames (and distances) at ``q_init``'s free knots, if known
            (:class:`KnotFrames`; CR passes those of its last solution, shifted).

    Returns:
        The best trajectory found, with the frames at its knots; the cost never increases from
        the initial guess.

    Raises:
        SolverError: if the cost is not finite or the Cholesky factorization fails.
        ConfigError: for invalid solver settings.
    """
    if not (damping > 0.0 and tolerance >= 0.0 and max_iterations >= 0):
        raise ConfigError.invalid(
            "solver settings",
            (max_iterations, tolerance, damping),
            "max_iterations >= 0, tolerance >= 0, damping > 0",
        )
    _retain_freed_memory()
    data = robot.model.createData()
    x = free_knots(robot, problem, initial_guess(problem) if q_init is None else q_init)
    if init_frames is not None and init_frames.poses.position.shape[2] != len(x):
        init_frames = None
    point = residuals(robot, data, problem, x, init_frames)
    if not math.isfinite(point.cost):
        raise SolverError(f"non-finite trajectory cost {point.cost} at the initial guess", problem)
    lam = max(damping, _INITIAL_DAMPING)
    converged, iterations = False, 0
    woken = np.zeros(point.residuals[2].shape, dtype=bool)  # pairs a rejected step pushed in
    current: Evaluation | None = None  # the normal equations at point, made when needed
    while iterations < max_iterations and not converged:
        iterations += 1
        if current is None:
            current = linearize(robot, problem, point)
        step = _damped_step(current, woken, lam, problem).reshape(x.shape)
        trial = residuals(robot, data, problem, point.x + step)
        cost, new_cost = point.cost, trial.cost
        if not math.isfinite(new_cost):
            raise SolverError(f"non-finite trajectory cost {new_cost}", problem)
        small_step = float(np.max(np.abs(step))) < tolerance
        if new_cost <= cost:
            converged = small_step or cost - new_cost <= tolerance * cost
            point, current = trial, None
            lam = max(damping, lam / 10.0)
        else:
            converged = small_step
            if not _wake_pushed_in(current, trial, woken):
                lam *= 10.0
    frames = None
    if point.poses is not None:
        frames = KnotFrames(point.poses, point.dist, problem.obstacles, problem.obstacle_radii)
    return TrajectorySolution(
        np.vstack([problem.q_start, point.x]), point.cost, iterations, converged, frames
    )
