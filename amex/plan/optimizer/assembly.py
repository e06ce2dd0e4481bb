"""One Gauss-Newton iteration's residuals, normal equations and damped band, compiled.

:class:`CompiledAssembly` is what :func:`~amex.plan.optimizer.levenberg.solve_trajectory` runs
on (CR's every outer step): the kinematics kernels, Pinocchio's final-term kinematics and
LAPACK's banded Cholesky, glued by a few compiled loops (:mod:`.assembly_kernels`) instead of
~60 numpy operations per iteration, with its band buffer and Pinocchio data kept from one solve
to the next. The numbers are those of the numpy functions it replaces (the oracle,
:class:`NumpyAssembly`: :func:`~.residuals.residuals`, :func:`~.linearize.linearize`, the damped
step) bit for bit; ``tests/plan/test_assembly.py`` compares them. The authors' proxy collision
term (``collision_cost=proxy``) runs on the oracle.

Over the 400-line guide (~505) on purpose: CR's outer step runs ``evaluate`` two or three
times, so the kernels' calls of the final terms, distances and gradients are written out in it
(the same calls, in the same order, as :func:`~.final_terms.final_terms` and
:class:`~amex.plan.batch_kinematics.BatchKinematics` make them), and the trials reuse two sets
of buffers (:meth:`CompiledAssembly.trial_buffers`): each layer less was measurable there
(issue #29, docs/results/speed.md). Each step that now runs as one compiled call
(:mod:`.iteration_kernels`) keeps its Python calls beside it: they are the path where numpy is
not on its own OpenBLAS, and with :mod:`.compiled_loop` switched off, the bit-for-bit oracle of
the compiled steps.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
from scipy.linalg import LinAlgError

from amex.core.errors import SolverError
from amex.plan.batch_kinematics import BatchPoses, CapsuleDistances, batch_kinematics
from amex.plan.kinematics_kernels import (
    capsule_sphere_distances,
    final_terms_joint,
    near_pairs,
    pair_gradients,
)
from amex.plan.optimizer.assembly_kernels import (
    damped_system,
    start_residuals,
    take_step,
    wake_pairs,
)
from amex.plan.optimizer.band import solve_band
from amex.plan.optimizer.blas import BOUND
from amex.plan.optimizer.final_terms import final_terms, final_weights
from amex.plan.optimizer.iteration_kernels import damped_solve, final_cost, final_products
from amex.plan.optimizer.loop_calls import robot_arrays
from amex.plan.optimizer.numpy_assembly import NumpyAssembly
from amex.plan.optimizer.residuals import GUARD, KnotFrames, acceleration_scale
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.robot import RobotModel

__all__ = ["CompiledAssembly", "CompiledSolve", "Iterate", "Linearized", "assembly_for"]

_LWA = pin.LOCAL_WORLD_ALIGNED
_new = tuple.__new__  # a NamedTuple made without its Python-level __new__ (the same tuple)
_NO_FLAGS = np.zeros((0, 0, 0), dtype=bool)
_NO_PAIRS = np.zeros(0, dtype=np.int64)
_NO_ROWS = np.zeros((0, 0))
#: An iterate's collision fields without collision term: cap, obs, knot, r_near.
_NONE = (_NO_PAIRS, _NO_PAIRS, _NO_PAIRS, np.zeros(0))


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
    cap: np.ndarray
    obs: np.ndarray
    knot: np.ndarray
    r_near: np.ndarray


class Linearized(NamedTuple):
    """What the damped steps at an iterate need beyond its residuals (the products numpy makes).

    Attributes:
        final_JtJ: ``J_fin^T J_fin``, shape (m, m), from row/column ``final_first``.
        final_Jtr: ``J_fin^T r_fin``, shape (m,).
        final_first: the first row of the final block.
        J_col: the near pairs' collision Jacobian rows, shape (P, n).
    """

    final_JtJ: np.ndarray
    final_Jtr: np.ndarray
    final_first: int
    J_col: np.ndarray


class _Constants(NamedTuple):
    """What a solve's costs and knot spacing fix (worked out once per costs object and dt)."""

    s_acc: np.ndarray  # acceleration residual factor per joint (n,)
    s_acc2: np.ndarray  # 2 s_acc (n,)
    band_scale: float  # 2 w_acc / dt^3
    metric: np.ndarray  # diag(H) (n,), or empty
    final_weights: np.ndarray  # square roots of the four final weights
    margin: float  # collision margin [m]
    s_col: float  # sqrt(w_col)
    collision: bool  # a collision term at all (w_col > 0 and capsules)
    w3: float  # the axis rate's weight root (final_weights[3])
    rate_rows: slice  # the axis rate's rows of the final residuals
    tcp_velocity: bool  # the final velocity of the TCP (the original's), not of the joints
    fixed: tuple[object, ...]  # what compiled_loop.levenberg_loop reads of these, in its order


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
        self.Jz = np.empty((3, robot.model.nv))  # the final terms' J_z, scratch
        self.rows = np.empty((3, robot.model.nv))  # J_w in C order, scratch (final_cost)
        self.compiled_robot, self.no_frames = robot_arrays(robot, self.kinematics)
        self.nv, self.capsules = int(robot.model.nv), len(robot.capsules)
        self.pinocchio = (robot.model, self.data, robot.tcp_frame_id)
        self._band, self._rhs = np.zeros((1, 0), order="F"), np.zeros(0)
        self._scratch = np.zeros((0, 0, 0))
        self._constants: tuple[object, float, _Constants] | None = None
        self._trials: list[tuple[np.ndarray, ...]] = []

    def trial_buffers(self, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """Knots, acceleration residuals, final velocity, final residuals and Jacobian buffers.

        Shaped for a trial from the iterate at ``x`` (T, n): (T, n), (T, n), (n,), (9 + n,),
        (9 + n, 2n). Two sets, taken in turn: never the set that holds ``x`` (the iterate a
        trial starts from stays intact; a solve holds at most that one and its trial).
        """
        T, n = x.shape
        trials = self._trials
        if not trials or trials[0][0].shape[0] < T or trials[0][0].shape[1] != n:
            rows = max(T, trials[0][0].shape[0] if trials else 0)
            trials[:] = [
                (np.empty((rows, n)), np.empty((rows, n)), np.empty(n), np.empty(9 + n))
                + (np.empty((9 + n, 2 * n)),)
                for _ in range(2)
            ]
        knots, r_acc, v_last, r_fin, J_fin = trials[1 if x.base is trials[0][0] else 0]
        return knots[:T], r_acc[:T], v_last, r_fin, J_fin

    def buffers(self, width: int, size: int) -> tuple[np.ndarray, np.ndarray]:
        """A Fortran-ordered (width, size) band and a (size,) vector, overwritten by each use."""
        band, rhs = self._band, self._rhs
        if band.shape[0] != width or band.shape[1] < size:
            band = self._band = np.empty((width, size), order="F")
            rhs = self._rhs = np.empty(size)
        return band[:, :size], rhs[:size]

    def scratch(self, shape: tuple[int, int, int]) -> np.ndarray:
        """A (C, k, T) array of undefined entries (written, never read)."""
        buffer = self._scratch
        if buffer.shape[:2] != shape[:2] or buffer.shape[2] < shape[2]:
            buffer = self._scratch = np.empty(shape)
        return buffer[:, :, : shape[2]]

    def begin(self, problem: TrajectoryProblem) -> CompiledSolve:
        """The solve of ``problem``."""
        return CompiledSolve(self, problem, self.constants(problem.costs, float(problem.dt)))

    def fuses(self) -> bool:
        """Whether the iteration's kernels call numpy's routines (:mod:`.iteration_kernels`).

        The routines must be bound (:data:`.blas.BOUND`, read at each call: ``bench_cr``
        unbinds them) and the arm must have two joints or more.
        """
        return BOUND and self.nv >= 2

    def loop_runs(self, constants: _Constants) -> bool:
        """Whether a solve of these constants can be one compiled call (:mod:`.compiled_loop`).

        :meth:`fuses`, and the joint-velocity final terms; the solve needs T >= 2 knots too.
        """
        return self.fuses() and not constants.tcp_velocity

    def constants(self, costs: TrajectoryCosts, dt: float) -> _Constants:
        """What ``costs`` and the knot spacing ``dt`` fix, worked out once for the last pair."""
        known = self._constants
        if known is None or known[0] is not costs or known[1] != dt:
            known = self._constants = (costs, dt, self._work_out(costs, dt))
        return known[2]

    def _work_out(self, c: TrajectoryCosts, dt: float) -> _Constants:
        n = self.robot.model.nv
        s_acc = acceleration_scale(c, dt)
        w = c.weights
        s_acc_n = np.full(n, s_acc) if isinstance(s_acc, float) else s_acc
        s_acc2 = np.full(n, 2.0 * s_acc) if isinstance(s_acc, float) else 2.0 * s_acc
        band_scale = 2.0 * float(w.acceleration) / dt**3
        metric = np.asarray(c.metric, dtype=float)
        weights = final_weights(c)
        margin, s_col = float(w.collision_margin), math.sqrt(w.collision)
        fixed = (dt, s_acc_n, band_scale, metric, s_acc2, weights, margin, s_col)
        return _Constants(
            s_acc_n,
            s_acc2,
            band_scale,
            metric,
            weights,
            margin,
            s_col,
            bool(self.robot.capsules) and w.collision > 0.0,
            weights[3],
            slice(6 + n, None),
            c.final_velocity_space == "tcp",
            fixed,
        )


class CompiledSolve:
    """The compiled iteration of one problem (:class:`CompiledAssembly`; module notes)."""

    def __init__(
        self, assembly: CompiledAssembly, problem: TrajectoryProblem, constants: _Constants
    ) -> None:
        self.assembly, self.problem, self.constants = assembly, problem, constants
        self.q_start, self.v_start, self.dt = problem.q_start, problem.v_start, problem.dt
        self.n, k = assembly.nv, len(problem.obstacle_radii)
        self.collides = constants.collision and k > 0
        self.shape = (assembly.capsules, k, problem.steps)
        self.fused = assembly.fuses()  # numpy's routines callable from compiled code
        # the whole solve compiled (compiled_loop): the joint-velocity final terms, T >= 2
        self.loop = assembly.loop_runs(constants) and problem.steps >= 2

    def woken(self) -> np.ndarray:
        """No pair woken yet: (C, k, T) flags (without obstacles the empty ones, shared)."""
        if self.shape[1] == 0:
            return _NO_FLAGS
        return np.zeros(self.shape, dtype=bool)

    def evaluate(
        self,
        x: np.ndarray,
        known: KnotFrames | None = None,
        r_acc: np.ndarray | None = None,
        v_last: np.ndarray | None = None,
        final: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> Iterate:
        """Residuals and cost at the free knots ``x`` (T, n) (:func:`~.residuals.residuals`).

        ``known``: the frames (and distances) at ``x``; ``r_acc``: its acceleration residuals;
        ``v_last``: its final joint velocity (:func:`~.assembly_kernels.take_step`); ``final``:
        buffers for the final residuals (9 + n,) and their Jacobian (9 + n, 2n).
        """
        problem, c, n, T = self.problem, self.constants, self.n, x.shape[0]
        if r_acc is None or v_last is None:
            r_acc, v_last = np.empty_like(x), np.empty(n)
            start_residuals(x, self.q_start, self.v_start, self.dt, c.s_acc, r_acc, v_last)
        model, data, fid = self.assembly.pinocchio
        cost: float | None = None
        if c.tcp_velocity:
            q_prev = x[-2] if T > 1 else self.q_start
            w = c.final_weights
            r_fin, J_fin = final_terms(model, data, fid, problem, q_prev, x[-1], w, v_last)
        else:  # final_terms' calls for the joint velocity, written out (two per iteration)
            pin.computeJointJacobians(model, data, x[-1])
            oMf = pin.updateFramePlacement(model, data, fid)
            J = pin.getFrameJacobian(model, data, fid, _LWA)
            r_fin, J_fin = (np.empty(9 + n), np.empty((9 + n, 2 * n))) if final is None else final
            Jz, goal, axis = self.assembly.Jz, problem.goal_pos, problem.goal_axis
            R, p, w = oMf.rotation, oMf.translation, c.final_weights
            if self.fused:  # the lines below and the cost in one call, numpy's routines included
                rows = self.assembly.rows
                cost = final_cost(
                    J, R, p, v_last, goal, axis, w, self.dt, rows, Jz, r_fin, J_fin, r_acc
                )
            else:
                Jwv = J[3:].dot(v_last)
                final_terms_joint(J, R, p, v_last, Jwv, goal, axis, w, self.dt, Jz, r_fin, J_fin)
                np.multiply(Jz.dot(v_last), c.w3, out=r_fin[c.rate_rows])  # w[3] (Jz @ v)
        if T == 1:  # q_{T-1} is the fixed start
            J_fin = J_fin[:, n:]
        if cost is None:
            flat_acc = r_acc.reshape(-1)
            cost = float(flat_acc.dot(flat_acc) + r_fin.dot(r_fin))  # numpy's ddot, as @ does
        if not self.collides:
            return _new(Iterate, (x, r_acc, r_fin, J_fin, cost, None, None, *_NONE))
        kin = self.assembly.kinematics
        poses = known.poses if known is not None else kin.forward(x)
        dist = None
        if known is not None and known.computed_for(problem.obstacles, problem.obstacle_radii):
            dist = known.dist
        if dist is None and T >= 2:  # capsule_distances' kernel call, its arrays at hand
            C, k = self.shape[0], self.shape[1]
            dist = CapsuleDistances(np.empty((C, k, T)), np.empty((C, k, 3, T)))
            capsule_sphere_distances(
                poses.rotation,
                poses.position,
                kin.cap_joint,
                kin.cap_ends,
                kin.cap_inv_len2,
                kin.cap_radius,
                problem.obstacles,
                problem.obstacle_radii,
                dist.distance,
                dist.offset,
            )
        elif dist is None:
            dist = kin.capsule_distances(poses, problem.obstacles, problem.obstacle_radii)
        scratch = self.assembly.scratch(self.shape)  # near_pairs' dense residuals, not read
        cap, obs, knot, r_near = near_pairs(dist.distance, c.margin, GUARD, c.s_col, scratch)
        if knot.size:
            cost += float(r_near.dot(r_near))
        return _new(Iterate, (x, r_acc, r_fin, J_fin, cost, poses, dist, cap, obs, knot, r_near))

    def linearize(self, point: Iterate) -> Linearized:
        """The pieces of ``2 J^T J`` and ``2 J^T r`` at ``point`` (as ``linearize``'s)."""
        J_fin = point.J_fin
        J_col = _NO_ROWS
        if point.knot.size and point.poses is not None and point.dist is not None:
            c = self.constants
            kin, poses = self.assembly.kinematics, point.poses
            J_col = np.empty((point.cap.shape[0], self.n))  # distance_gradients' kernel call
            pair_gradients(
                poses.axis,
                poses.position,
                point.dist.offset,
                self.problem.obstacles,
                kin.cap_support,
                point.cap,
                point.obs,
                point.knot,
                J_col,
            )
            J_col *= -c.s_col / c.margin
        first = self.n * point.x.shape[0] - J_fin.shape[1]
        # numpy's gemv either way; dot has less overhead, and calls it as @ does for the whole
        # (contiguous) Jacobian only, not for the T = 1 view of its last columns
        if J_fin.flags.c_contiguous:
            if self.fused:  # numpy's syrk and gemv, in one call
                return _new(Linearized, (*final_products(J_fin, point.r_fin), first, J_col))
            Jtr = J_fin.T.dot(point.r_fin)
        else:
            Jtr = J_fin.T @ point.r_fin
        return _new(Linearized, (J_fin.T @ J_fin, Jtr, first, J_col))

    def system_terms(
        self, point: Iterate, model: Linearized, woken: np.ndarray, lam: float
    ) -> tuple[Any, ...]:
        """The damped system's terms after the band and right-hand side, in the kernels' order.

        :func:`~.assembly_kernels.damped_system` and :func:`~.iteration_kernels.damped_solve`
        take them after their two buffers.
        """
        c = self.constants
        return (
            c.band_scale,
            c.metric,
            model.final_JtJ,
            model.final_Jtr,
            model.final_first,
            point.r_acc,
            c.s_acc2,
            point.cap,
            point.obs,
            point.knot,
            model.J_col,
            point.r_near,
            woken,
            lam,
        )

    def system(
        self, point: Iterate, model: Linearized, woken: np.ndarray, lam: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The damped step's band ``H + G + lambda I`` and right-hand side ``-g`` (buffers)."""
        band, rhs = self.assembly.buffers(2 * self.n + 1, point.r_acc.size)
        damped_system(band, rhs, *self.system_terms(point, model, woken, lam))
        return band, rhs

    def damped_step(
        self, point: Iterate, model: Linearized, woken: np.ndarray, lam: float
    ) -> np.ndarray:
        """``dx`` (nT,) of ``(H + G + lambda I) dx = -g`` (the numpy damped step's)."""
        if self.fused:  # system and solve_band in one call (the same LAPACK routine)
            return self._fused_step(point, model, woken, lam)
        band, rhs = self.system(point, model, woken, lam)
        try:
            return solve_band(band, rhs)
        except (LinAlgError, ValueError) as e:
            raise SolverError(f"Gauss-Newton Cholesky failed: {e}", self.problem) from e

    def _fused_step(
        self, point: Iterate, model: Linearized, woken: np.ndarray, lam: float
    ) -> np.ndarray:
        band, rhs = self.assembly.buffers(2 * self.n + 1, point.r_acc.size)
        info = damped_solve(band, rhs, *self.system_terms(point, model, woken, lam))
        if info == 0:
            return rhs
        self.raise_cholesky(info)
        raise AssertionError  # (unreachable: raise_cholesky raises)

    def raise_cholesky(self, info: int) -> None:
        """Raise :func:`~.band.solve_band`'s error for LAPACK's ``info`` as a SolverError."""
        error: Exception
        if info > 0:
            error = LinAlgError(f"{info}th leading minor not positive definite")
        else:
            error = ValueError(f"illegal value in {-info}th argument of internal pbsv")
        raise SolverError(f"Gauss-Newton Cholesky failed: {error}", self.problem) from error

    def step(self, point: Iterate, step: np.ndarray, tolerance: float) -> tuple[Iterate, bool]:
        """The iterate at ``point.x + step`` and whether ``max |step| < tolerance`` [rad]."""
        x = point.x
        out, r_acc, v_last, r_fin, J_fin = self.assembly.trial_buffers(x)
        small = take_step(
            x,
            step,
            self.q_start,
            self.v_start,
            self.dt,
            self.constants.s_acc,
            tolerance,
            out,
            r_acc,
            v_last,
        )
        return self.evaluate(out, None, r_acc, v_last, (r_fin, J_fin)), small

    def wake(self, point: Iterate, trial: Iterate, woken: np.ndarray, model: Linearized) -> bool:
        """Wake the pairs inactive at ``point`` that ``trial`` made active; whether any."""
        if not point.knot.size or trial.dist is None:
            return False
        c = self.constants
        return bool(
            wake_pairs(
                point.cap,
                point.obs,
                point.knot,
                point.r_near,
                trial.dist.distance,
                c.margin,
                c.s_col,
                woken,
            )
        )

    def frames(self, point: Iterate) -> KnotFrames | None:
        """The frames and distances at ``point``'s knots (None without collision term)."""
        if point.poses is None:
            return None
        problem = self.problem
        return KnotFrames(point.poses, point.dist, problem.obstacles, problem.obstacle_radii)


def assembly_for(
    robot: RobotModel,
    problem: TrajectoryProblem,
    assembly: CompiledAssembly | NumpyAssembly | None = None,
) -> CompiledAssembly | NumpyAssembly:
    """The iteration to solve ``problem`` on, compiled unless the authors' proxy is in play.

    ``assembly`` (a new compiled one if None or of another robot), or the numpy one where the
    proxy collision term is active (obstacles, capsules and a weight).
    """
    costs = problem.costs
    mine = isinstance(assembly, CompiledAssembly) and assembly.robot is robot
    if mine and costs.collision_cost != "proxy":
        return assembly  # type: ignore[return-value]  # CR's every step (checked: compiled)
    w = costs.weights
    collides = len(problem.obstacle_radii) and robot.capsules and w.collision > 0.0
    if problem.costs.collision_cost == "proxy" and collides:
        return NumpyAssembly(robot)
    if assembly is None or assembly.robot is not robot:
        return CompiledAssembly(robot)
    return assembly
