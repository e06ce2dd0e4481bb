"""Our trajectory solver: Levenberg-damped Gauss-Newton on the banded normal equations.

Each iteration solves ``(2 J^T J + lambda I) dx = -2 J^T r`` (one banded Cholesky) and evaluates
the cost at ``x + dx``; the paper's reference planner ("quadratic cost terms and a Gauss-Newton
optimizer", Section IV) and CR's replanning (Section IV-A). Step rules and measurements:
docs/planner.md.
"""

from __future__ import annotations

import math

import numpy as np

from amex.core.errors import ConfigError, SolverError
from amex.plan.optimizer import compiled_loop
from amex.plan.optimizer.assembly import CompiledAssembly, CompiledSolve, assembly_for
from amex.plan.optimizer.compiled_loop import INITIAL_DAMPING
from amex.plan.optimizer.loop_calls import retain_freed_memory, solve_compiled
from amex.plan.optimizer.numpy_assembly import NumpyAssembly
from amex.plan.optimizer.residuals import KnotFrames, free_knots, initial_guess
from amex.plan.problem import TrajectoryProblem, TrajectorySolution
from amex.robot import RobotModel

__all__ = ["solve_trajectory"]

_F64 = np.dtype(np.float64)


def solve_trajectory(
    robot: RobotModel,
    problem: TrajectoryProblem,
    q_init: np.ndarray | None = None,
    max_iterations: int = 20,
    tolerance: float = 1e-4,
    damping: float = 1e-3,
    init_frames: KnotFrames | None = None,
    assembly: CompiledAssembly | NumpyAssembly | None = None,
    compiled: bool = False,
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
        assembly: the iteration's implementation and buffers (:mod:`.assembly`; CR passes
            its own, kept between solves); default: a new :class:`CompiledAssembly`. The
            authors' proxy collision term, where in play, runs on :class:`NumpyAssembly`, the
            numpy oracle, which gives the same numbers (:func:`~.assembly.assembly_for`).
        compiled: run the whole solve as one compiled call where it can
            (:mod:`.compiled_loop`: its final-term kinematics round differently from
            Pinocchio's in the last bits). CR's replanning does; the reference plan, which every
            method follows, keeps this Python loop and its numbers bit for bit.

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
    retain_freed_memory()
    solve = assembly_for(robot, problem, assembly).begin(problem)
    steps = problem.steps
    if type(q_init) is np.ndarray and q_init.dtype is _F64 and q_init.shape[0] == steps + 1:
        if q_init.shape[1:] == (robot.model.nq,):
            x = q_init[1:]  # free_knots' answer, without its checks' call (CR's every step)
        else:
            x = free_knots(robot, problem, q_init)
    else:
        x = free_knots(robot, problem, initial_guess(problem) if q_init is None else q_init)
    if init_frames is not None and init_frames.poses.position.shape[2] != steps:
        init_frames = None
    if compiled and compiled_loop.ENABLED and type(solve) is CompiledSolve and solve.loop:
        return solve_compiled(solve, x, init_frames, max_iterations, tolerance, damping)
    point = solve.evaluate(x, init_frames)
    if not math.isfinite(point.cost):
        problem.check()  # a non-finite input named, where that is the cause
        raise SolverError(f"non-finite trajectory cost {point.cost} at the initial guess", problem)
    lam = max(damping, INITIAL_DAMPING)
    converged, iterations = False, 0
    woken = solve.woken()  # pairs a rejected step pushed in
    current = None  # the normal equations at point, made when needed
    while iterations < max_iterations and not converged:
        iterations += 1
        if current is None:
            current = solve.linearize(point)  # type: ignore[arg-type]
        step = solve.damped_step(point, current, woken, lam)  # type: ignore[arg-type]
        trial, small_step = solve.step(point, step, tolerance)  # type: ignore[arg-type]
        cost, new_cost = point.cost, trial.cost
        if not math.isfinite(new_cost):
            raise SolverError(f"non-finite trajectory cost {new_cost}", problem)
        if new_cost <= cost:
            converged = small_step or cost - new_cost <= tolerance * cost
            point, current = trial, None
            lam = max(damping, lam / 10.0)
        else:
            converged = small_step
            if not solve.wake(point, trial, woken, current):  # type: ignore[arg-type]
                lam *= 10.0
    q = np.concatenate((problem.q_start[None], point.x))
    frames = solve.frames(point)  # type: ignore[arg-type]
    return tuple.__new__(TrajectorySolution, (q, point.cost, iterations, converged, frames))
