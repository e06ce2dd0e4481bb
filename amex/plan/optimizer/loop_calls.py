"""The compiled loop's callers' side: its arguments put together, its answer made a solution.

:func:`~.compiled_loop.levenberg_loop` takes the problem, the robot and the warm start as tuples
of arrays and returns its outcome, the solution's knots and frames as arrays. Here are the two
ways in: :func:`solve_compiled`, the end of :func:`~.levenberg.solve_trajectory` (its problem
and :class:`~.assembly.CompiledSolve` at hand), and :class:`ReplanLoop`, CR's usual step, which
puts together once what stays from one step to the next and passes the rest as it comes. Both
make the same call on the same arguments through :func:`_run`, and so get the same numbers.
"""

from __future__ import annotations

import ctypes
from functools import cache
from typing import TYPE_CHECKING, Any

import numpy as np

from amex.core.errors import SolverError
from amex.plan.batch_kinematics import BatchKinematics, BatchPoses, CapsuleDistances
from amex.plan.optimizer import compiled_loop as kernel
from amex.plan.optimizer.residuals import KnotFrames
from amex.plan.problem import TrajectorySolution

if TYPE_CHECKING:
    from amex.robot import RobotModel

__all__ = ["ReplanLoop", "retain_freed_memory", "robot_arrays", "solve_compiled"]

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc mallopt parameters
_TRIM_THRESHOLD = 64 << 20  # [bytes] free heap glibc keeps instead of returning it to the OS
_MMAP_THRESHOLD = 32 << 20  # [bytes] smallest block mapped on its own (glibc's largest allowed)


@cache
def retain_freed_memory() -> bool:
    """Keep glibc from returning freed memory to the OS (``mallopt``, trim and mmap thresholds).

    An evaluation at 400 knots allocates and frees ~1 MB; with glibc's default trim threshold
    each one page-faults the heap top in again (docs/planner.md). Setting the trim threshold
    also fixes glibc's mmap threshold at its 128 KiB start (it no longer grows with the blocks
    freed), so each larger array (the band at 400 knots: 330 KiB) would be mapped, faulted in
    and unmapped at every call: the mmap threshold is raised with it. Process-wide settings
    with no effect on results, made once; a no-op (False) where mallopt is missing.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError, TypeError):
        return False
    trim = mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD)
    return bool(mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD) and trim)


def robot_arrays(
    robot: RobotModel, kin: BatchKinematics
) -> tuple[tuple[object, ...], tuple[np.ndarray, ...]]:
    """The arm's arrays the compiled loop reads, and its frames over zero knots.

    The TCP's point and rotation in its joint's turned frame (as
    :meth:`~amex.plan.batch_kinematics.BatchKinematics.frame_positions` turns them) and the
    joints that move it; the capsules' tables; frames and distances over zero knots.
    """
    frame = robot.model.frames[robot.tcp_frame_id]
    joint = int(frame.parentJoint)
    turn = kin.turn[joint]
    support = np.zeros(robot.model.nv, dtype=bool)
    j = joint
    while j > 0:
        support[j - 1] = True
        j = kin.parents[j]
    arrays = (
        kin.local,
        kin.parents_array,
        joint,
        np.ascontiguousarray(turn.T @ frame.placement.translation),
        np.ascontiguousarray(turn.T @ frame.placement.rotation),
        support,
        kin.cap_joint,
        kin.cap_ends,
        kin.cap_inv_len2,
        kin.cap_radius,
        kin.cap_support,
    )
    C, nj = len(kin.cap_joint), kin.njoints
    empty = (
        np.empty((nj, 3, 3, 0)),
        np.empty((nj, 3, 0)),
        np.empty((C, 0, 0)),
        np.empty((C, 0, 3, 0)),
    )
    return arrays, empty


def solve_compiled(
    solve: Any,
    x: np.ndarray,
    init_frames: KnotFrames | None,
    max_iterations: int,
    tolerance: float,
    damping: float,
) -> TrajectorySolution:
    """The compiled loop from the free knots ``x`` (T, n): the Python loop's solution.

    ``solve``: the :class:`~.assembly.CompiledSolve` of the problem (not imported here: the
    assembly imports this module).

    Raises:
        SolverError: as :func:`~.levenberg.solve_trajectory` raises it.
    """
    problem, assembly = solve.problem, solve.assembly
    settings = (int(max_iterations), float(tolerance), float(damping), kernel.INITIAL_DAMPING)
    arrays = (problem.q_start, problem.v_start, problem.goal_pos, problem.goal_axis)
    obstacles = (problem.obstacles, problem.obstacle_radii)
    out = _run(assembly, solve.constants.fixed, solve.collides, settings, _NO_TARGET, x, 0,
               init_frames, arrays, obstacles)  # fmt: skip
    outcome, value = out[0], out[1]
    if outcome == kernel.BAD_START:
        problem.check()  # a non-finite input named, where that is the cause
        raise SolverError(f"non-finite trajectory cost {value} at the initial guess", problem)
    if outcome == kernel.BAD_TRIAL:
        raise SolverError(f"non-finite trajectory cost {value}", problem)
    if outcome in (kernel.NOT_DEFINITE, kernel.ILLEGAL):
        solve.raise_cholesky(int(value))
    return _solution(out, solve.collides, obstacles)


class ReplanLoop:
    """The compiled loop for one solve after another of a robot, costs and knot spacing.

    CR's every outer step. What stays from solve to solve (the costs' constants, the robot's
    arrays, the solver's settings, the target's stride) is put together once, and a solve
    passes only what changes: the same call :func:`~.levenberg.solve_trajectory` makes with
    ``compiled=True``, on the same arguments, so the same numbers, without the ~10 us of Python
    it spends on the problem's objects. :meth:`solve` answers None where that path would not run
    the loop, or where the loop did not solve: the caller then solves through
    ``solve_trajectory``, which raises the error with its problem.

    Args:
        assembly: the robot's :class:`~.assembly.CompiledAssembly` (its buffers and arrays).
        costs: the problems' costs (:class:`~amex.plan.problem.TrajectoryCosts`).
        dt: their knot spacing [s].
        settings: ``(max_iterations, tolerance, damping)`` (lambda starts at
            :data:`~.compiled_loop.INITIAL_DAMPING`, as in ``solve_trajectory``).
        target: ``(stride, dt)`` of the joint target computed from each solution
            (:func:`~amex.plan.knots_kernels.midpoint_target`; stride 0: none).
    """

    def __init__(
        self,
        assembly: Any,
        costs: Any,
        dt: float,
        settings: tuple[int, float, float],
        target: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        retain_freed_memory()
        c = assembly.constants(costs, dt)
        self.assembly, self.costs, self.dt = assembly, costs, float(dt)
        self.fixed, self.collision = c.fixed, c.collision
        iterations, tolerance, damping = settings
        self.settings = (int(iterations), float(tolerance), float(damping), kernel.INITIAL_DAMPING)
        self.target = (float(target[0]), float(target[1]))
        self.usable = assembly.loop_runs(c) and costs.collision_cost != "proxy"

    def solve(
        self,
        x: np.ndarray,
        frames: KnotFrames | None,
        first: int,
        q_start: np.ndarray,
        v_start: np.ndarray,
        goal_pos: np.ndarray,
        goal_axis: np.ndarray,
        obstacles: np.ndarray,
        radii: np.ndarray,
    ) -> tuple[TrajectorySolution, np.ndarray, np.ndarray] | None:
        """The solution from the free knots ``x`` (T, n), and its joint target ``(q_mid, qd)``.

        ``frames``: the last solution's, whose free knots ``first .. first + T - 1`` are those of
        ``x`` (CR's shift by whole knots), or None. The arrays are float64 of the problem's
        shapes and finite (:meth:`~amex.plan.problem.TrajectoryProblem.prechecked`'s terms); the
        obstacles are copied where the solution's frames keep them. None: solve through
        :func:`~.levenberg.solve_trajectory` instead (class notes).
        """
        if not (kernel.ENABLED and self.usable and x.shape[0] >= 2):
            return None
        collides = self.collision and radii.shape[0] > 0
        if collides:
            obstacles, radii = obstacles.copy(), radii.copy()
        kept = (obstacles, radii)
        arrays = (q_start, v_start, goal_pos, goal_axis)
        out = _run(self.assembly, self.fixed, collides, self.settings, self.target, x, first,
                   frames, arrays, kept)  # fmt: skip
        if out[0] != kernel.SOLVED:
            return None
        return _solution(out, collides, kept), out[10], out[11]


#: No joint target (:func:`~.compiled_loop.levenberg_loop`'s ``target``).
_NO_TARGET = (0.0, 0.0)


def _run(
    assembly: Any,
    fixed: tuple[object, ...],
    collides: bool,
    settings: tuple[int, float, float, float],
    target: tuple[float, float],
    x: np.ndarray,
    first: int,
    frames: KnotFrames | None,
    arrays: tuple[np.ndarray, ...],
    obstacles: tuple[np.ndarray, np.ndarray],
) -> tuple[Any, ...]:
    """The compiled loop with the frames of ``frames``' free knots ``first .. first + T - 1``.

    They are used where they span T knots and there is a collision term, their distances where
    they were computed for the same obstacles (as :meth:`~.assembly.CompiledSolve.evaluate`
    uses a warm start's frames).
    """
    known: tuple[np.ndarray, ...] = assembly.no_frames
    use_known = reuse = False
    T = x.shape[0]
    if frames is not None and collides:
        poses, dist = frames.poses, frames.dist
        stop = first + T
        position = poses.position[..., first:stop]
        if position.shape[2] == T:
            use_known = True
            reuse = dist is not None and frames.computed_for(*obstacles)
            rotation = poses.rotation[..., first:stop]
            if dist is None:  # computed again (reuse is False)
                known = (rotation, position, known[2], known[3])
            else:
                known = (rotation, position, dist.distance[..., first:stop],
                         dist.offset[..., first:stop])  # fmt: skip
    band, rhs = assembly.buffers(2 * x.shape[1] + 1, x.size)
    problem = (*arrays, *obstacles, collides)
    return kernel.levenberg_loop(
        x, fixed, problem, assembly.compiled_robot, known, use_known, reuse, settings, band, rhs,
        target,
    )  # fmt: skip


def _solution(
    out: tuple[Any, ...], collides: bool, obstacles: tuple[np.ndarray, np.ndarray]
) -> TrajectorySolution:
    """The :class:`TrajectorySolution` of the compiled loop's answer ``out``."""
    q, cost, iterations, converged, axes, pos, distance, offset = out[2:10]
    frames = None
    if collides:
        poses = tuple.__new__(BatchPoses, (axes, pos, axes[:, 2]))
        dist = tuple.__new__(CapsuleDistances, (distance, offset))
        frames = tuple.__new__(KnotFrames, (poses, dist, *obstacles))
    return tuple.__new__(TrajectorySolution, (q, cost, iterations, converged, frames))
