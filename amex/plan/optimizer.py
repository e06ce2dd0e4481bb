"""Gauss-Newton trajectory optimization in joint space with a banded normal-equation solve.

The paper plans its reference with "a trajectory optimizer that uses quadratic cost terms and a
Gauss-Newton optimizer" (Section IV) and continuous replanning (CR, Section IV-A) re-runs the same
optimizer every outer step, warm-started. DESIGN.md ("The original experiment": Reference plan, CR)
fixes the costs. The decision variables are the knots ``x = (q_1, ..., q_T)``, shape (T, 7) [rad];
``q_0`` is the measured start and ``q_-1 = q_0 - dt * v_0``. With residuals ``r(x)`` the cost is

    f(x) = w_acc  sum_{t=0}^{T-1} ||(q_{t+1} - 2 q_t + q_{t-1}) / dt^2||^2 dt
         + w_pos  ||p(q_T) - g||^2          + w_vel   ||(q_T - q_{T-1}) / dt||^2
         + w_axis ||z(q_T) - a||^2          + w_axvel ||J_z(q_T) (q_T - q_{T-1}) / dt||^2
         + w_col  sum_{t=1}^{T} sum_{capsule, obstacle} max(0, 1 - d / margin)^2  =  ||r(x)||^2,

with p, z the TCP position and z-axis. The collision residual ``1 - d / margin`` is the original
code's proxy cost (MLR ``kinematicsProxyCost``), per pair instead of summed over pairs first:
dimensionless, 0 at the margin and 1 at contact, summed over knots without a ``dt`` factor. So
with weight 1 one knot in contact costs 1, about 14x the whole reference plan's acceleration cost
(0.07), and the optimum keeps pairs at or just outside the margin.

Gauss-Newton solves ``(2 J^T J + lambda I) dx = -2 J^T r``. Knot-major ordering makes the matrix
banded: acceleration couples a joint with itself two knots away (offset 2n), the final terms
couple the last two knots (offset < 2n) and collisions add 7x7 blocks on the diagonal, so the
bandwidth is exactly ``2n = 14`` (not the ``3n - 1 = 20`` of dense blocks, which makes LAPACK's
banded Cholesky ~3x slower) and each step is one ``solveh_banded`` call, O(T n^3). The collision
term needs kinematics at every knot: it runs batched over all knots in numpy
(:mod:`amex.plan.batch_kinematics`, re-exported here).
"""

from __future__ import annotations

import ctypes
import math
from functools import cache, lru_cache
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from scipy.linalg import LinAlgError, solveh_banded
from scipy.linalg.lapack import dpbsv as _dpbsv

from amex.core.errors import ConfigError, SolverError
from amex.plan.batch_kinematics import (
    BatchKinematics,
    BatchPoses,
    CapsuleDistances,
    batch_kinematics,
)
from amex.plan.kinematics_kernels import final_terms_joint, near_pairs
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem, TrajectorySolution
from amex.robot import RobotModel
from amex.robot.geometry import skew

__all__ = [
    "BatchKinematics",
    "BatchPoses",
    "CapsuleDistances",
    "KnotFrames",
    "NormalEquations",
    "TrajectoryCosts",
    "TrajectoryProblem",
    "TrajectorySolution",
    "batch_kinematics",
    "build_normal_equations",
    "shift_warm_start",
    "solve_trajectory",
    "solve_trajectory_newton",
    "trajectory_residuals",
]

_LWA = pin.LOCAL_WORLD_ALIGNED
_INITIAL_DAMPING = 1.0  # Levenberg lambda of the first iteration (see solve_trajectory)
_GUARD = 0.25  # pairs within (1 + _GUARD) margins may add curvature (see solve_trajectory)
_M_TRIM_THRESHOLD = -1  # glibc mallopt parameter
_TRIM_THRESHOLD = 64 << 20  # [bytes] free heap glibc keeps instead of returning it to the OS


class NormalEquations(NamedTuple):
    """Gauss-Newton model of f at x, ``f(x + dx) ~ f + gradient . dx + dx^T hessian dx / 2``.

    Attributes:
        hessian: ``2 J^T J`` in LAPACK lower band storage (``solveh_banded(..., lower=True)``),
            ``hessian[i - j, j] = H[i, j]`` for ``0 <= i - j <= 2n``, shape (2n + 1, nT), in
            Fortran order (as LAPACK reads it: no copy before each solve); its entries are
            updated in place through :func:`_band_memory`.
        gradient: ``2 J^T r``, shape (nT,) for knots q_1..q_T stacked knot-major.
        cost: f(x).
    """

    hessian: np.ndarray
    gradient: np.ndarray
    cost: float


@cache
def _retain_freed_memory() -> bool:
    """Keep glibc from returning freed heap memory to the OS (``mallopt(M_TRIM_THRESHOLD)``).

    An evaluation at 400 knots allocates ~1 MB of arrays and frees them again. With glibc's
    default trim threshold the heap top is handed back to the OS after every evaluation and the
    next one page-faults it in again: ~270 faults per evaluation, measured here to triple its
    cost (3.4 ms instead of 1.2 ms with an obstacle). Keeping up to 64 MB of freed heap removes
    the faults; it is a process-wide setting with no effect on results. A no-op (False) where
    mallopt is missing.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError, TypeError):
        return False
    return bool(mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD))


@lru_cache(maxsize=8)
def _acceleration_band(
    n: int, T: int, dt: float, weight: float, metric: tuple[float, ...] = ()
) -> np.ndarray:
    """``2 J_acc^T J_acc`` in lower band storage (2n subdiagonals), shape (2n + 1, nT); read-only.

    J_acc is ``sqrt(weight dt) / dt^2`` times the second-difference operator D on the free knots,
    so the matrix is ``kron(D^T D, I_n)`` scaled (``kron(D^T D, H)`` with a joint ``metric``
    diag(H)); D^T D is pentadiagonal: diagonal 6 (5 and 1 at the last two knots), first
    off-diagonal -4 (-2 at the last), second off-diagonal 1.
    """
    scale = 2.0 * weight / dt**3
    band = np.zeros((2 * n + 1, n * T))
    band[0] = 6.0 * scale
    band[0, n * max(T - 2, 0) : n * max(T - 1, 0)] = 5.0 * scale
    band[0, n * (T - 1) :] = scale
    band[n, : n * max(T - 1, 0)] = -4.0 * scale
    band[n, n * max(T - 2, 0) : n * max(T - 1, 0)] = -2.0 * scale
    band[2 * n, : n * max(T - 2, 0)] = scale
    if metric:  # every band entry couples a joint with itself: scale its column by H_jj
        band *= np.tile(np.asarray(metric, dtype=float), T)
    band = np.asfortranarray(band)  # LAPACK's layout (NormalEquations)
    band.flags.writeable = False
    return band


@lru_cache(maxsize=4)
def _lower_triangle(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the lower triangle of an (m, m) matrix, ``i >= j``."""
    i, j = np.tril_indices(m)
    return i, j


def _add_block(band: np.ndarray, block: np.ndarray, first: int) -> None:
    """Add a symmetric ``block`` starting at row/column ``first`` to a lower band matrix."""
    i, j = _lower_triangle(block.shape[0])
    _band_memory(band)[(first + j) * band.shape[0] + (i - j)] += block[i, j]


def _band_memory(band: np.ndarray) -> np.ndarray:
    """A Fortran-ordered band as a flat view: entry ``[d, col]`` is at ``col * (2n + 1) + d``."""
    return band.T.reshape(-1)


def _acceleration_scale(costs: TrajectoryCosts, dt: float) -> float | np.ndarray:
    """Factor of the second differences in the acceleration residuals.

    ``sqrt(w dt) / dt^2``, times ``sqrt(H_jj)`` per joint with a joint metric (then shape (n,)).
    """
    s_acc = math.sqrt(costs.acceleration * dt) / dt**2
    if costs.metric:
        return s_acc * np.sqrt(np.asarray(costs.metric, dtype=float))
    return s_acc


@lru_cache(maxsize=16)
def _final_weights(costs: TrajectoryCosts) -> np.ndarray:
    """Square roots of the four final weights (position, velocity, axis, axis rate)."""
    c = costs
    w = np.sqrt([c.final_position, c.final_velocity, c.final_axis, c.final_axis_velocity])
    w.flags.writeable = False
    return w


def _final_terms(
    model: pin.Model,
    data: pin.Data,
    fid: int,
    problem: TrajectoryProblem,
    q_prev: np.ndarray,
    q_last: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of the four final terms, shape (m,), and their Jacobian, shape (m, 2n).

    The Jacobian columns are (q_{T-1}, q_T). Rows: position, joint velocity, axis, axis rate.
    The axis-rate derivative uses ``d omega / d q_i = z_i x sum_{k>i} z_k v_k`` (serial chain).
    With a joint final velocity (ours) the arithmetic is one compiled call
    (:func:`~amex.plan.kinematics_kernels.final_terms_joint`), bit for bit
    :func:`_final_terms_numpy`, which the TCP velocity (the original's) uses.
    """
    c, dt, n = problem.costs, problem.dt, len(q_last)
    if c.final_velocity_space == "tcp":
        return _final_terms_numpy(model, data, fid, problem, q_prev, q_last)
    pin.computeJointJacobians(model, data, q_last)
    oMf = pin.updateFramePlacement(model, data, fid)
    J = pin.getFrameJacobian(model, data, fid, _LWA)
    v = (q_last - q_prev) / dt
    Jz = np.empty((3, n))
    residual = np.empty(9 + n)
    jac = np.empty((9 + n, 2 * n))
    w = _final_weights(c)
    final_terms_joint(
        J,
        np.ascontiguousarray(oMf.rotation[:, 2]),
        oMf.translation,
        v,
        J[3:] @ v,
        problem.goal_pos,
        problem.goal_axis,
        w,
        float(dt),
        Jz,
        residual,
        jac,
    )
    residual[6 + n :] = w[3] * (Jz @ v)
    return residual, jac


def _final_terms_numpy(
    model: pin.Model,
    data: pin.Data,
    fid: int,
    problem: TrajectoryProblem,
    q_prev: np.ndarray,
    q_last: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_final_terms` in numpy (the reference of the compiled version; the original's)."""
    c, dt, n = problem.costs, problem.dt, len(q_last)
    pin.computeJointJacobians(model, data, q_last)
    oMf = pin.updateFramePlacement(model, data, fid)
    J = pin.getFrameJacobian(model, data, fid, _LWA)
    z = oMf.rotation[:, 2]
    Jw = J[3:]
    Jz = -skew(z) @ Jw
    v = (q_last - q_prev) / dt
    omega_after = np.cumsum((Jw * v)[:, ::-1], axis=1)[:, ::-1] - Jw * v  # sum_{k>i} z_k v_k
    domega = np.stack(
        [
            Jw[1] * omega_after[2] - Jw[2] * omega_after[1],
            Jw[2] * omega_after[0] - Jw[0] * omega_after[2],
            Jw[0] * omega_after[1] - Jw[1] * omega_after[0],
        ]
    )
    dzdot = -skew(z) @ domega + skew(Jw @ v) @ Jz
    w = np.sqrt([c.final_position, c.final_velocity, c.final_axis, c.final_axis_velocity])
    eye = np.eye(n) / dt
    p_last = oMf.translation
    if c.final_velocity_space == "tcp":  # (p(q_T) - p(q_{T-1})) / dt, as the original's
        p_last, z = p_last.copy(), z.copy()  # data is about to hold q_{T-1}
        J_last = J[:3].copy()
        pin.computeJointJacobians(model, data, q_prev)
        p_prev = pin.updateFramePlacement(model, data, fid).translation.copy()
        J_prev = pin.getFrameJacobian(model, data, fid, _LWA)[:3]
        vel, d_prev, d_last = (p_last - p_prev) / dt, -J_prev / dt, J_last / dt
    else:  # the joint velocity (q_T - q_{T-1}) / dt
        vel, d_prev, d_last = v, -eye, eye
    m = len(vel)
    residual = np.concatenate(
        [
            w[0] * (p_last - problem.goal_pos),
            w[1] * vel,
            w[2] * (z - problem.goal_axis),
            w[3] * (Jz @ v),
        ]
    )
    jac = np.zeros((9 + m, 2 * n))
    jac[0:3, n:] = w[0] * J[:3]
    jac[3 : 3 + m, :n], jac[3 : 3 + m, n:] = w[1] * d_prev, w[1] * d_last
    jac[3 + m : 6 + m, n:] = w[2] * Jz
    jac[6 + m :, :n], jac[6 + m :, n:] = -w[3] * Jz / dt, w[3] * (Jz / dt + dzdot)
    return residual, jac


class _Guard(NamedTuple):
    """Collision pairs within ``1 + _GUARD`` margins and their ``2 J^T J`` blocks."""

    pairs: tuple[np.ndarray, np.ndarray, np.ndarray]  # (capsule, obstacle, knot), sorted by knot
    outer: np.ndarray  # (P, n (n + 1) / 2) lower-triangle entries of each pair's 2 J^T J
    first: np.ndarray  # index of each knot's first pair
    flat: np.ndarray  # flat indices of the knots' blocks in the band

    def curvature(self, mask: np.ndarray) -> np.ndarray:
        """Summed blocks of the pairs in ``mask``, aligned with ``flat``."""
        return np.add.reduceat(self.outer * mask[:, None], self.first, axis=0).ravel()


class _Point(NamedTuple):
    """The residuals at the free knots ``x`` and what their derivatives reuse.

    Attributes:
        x: free knots, shape (T, n) [rad].
        residuals: acceleration (T, n), final (m,), collision (C, k, T) (zeros when inactive).
        cost: f(x).
        final_jacobian: Jacobian of the final residuals, columns (q_{T-1}, q_T) or q_T alone.
        poses: batched joint frames (None without collision term).
        dist: capsule-obstacle distances (None without collision term).
        near: pairs within ``1 + _GUARD`` margins, (capsule, obstacle, knot) sorted by knot.
    """

    x: np.ndarray
    residuals: list[np.ndarray]
    cost: float
    final_jacobian: np.ndarray
    poses: BatchPoses | None
    dist: CapsuleDistances | None
    near: tuple[np.ndarray, np.ndarray, np.ndarray] | None


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

    def take(self, columns: np.ndarray) -> KnotFrames:
        """The frames of the free knots ``columns`` (indices into these), in that order."""
        rotation = self.poses.rotation[..., columns]
        poses = BatchPoses(rotation, self.poses.position[..., columns], rotation[:, 2])
        dist = None
        if self.dist is not None:
            d = self.dist
            dist = CapsuleDistances(d.distance[..., columns], d.offset[..., columns])
        return KnotFrames(poses, dist, self.obstacles, self.radii)

    def distances(self, problem: TrajectoryProblem) -> CapsuleDistances | None:
        """The distances, if computed for the obstacles of ``problem``."""
        same = np.array_equal(self.obstacles, problem.obstacles) and np.array_equal(
            self.radii, problem.obstacle_radii
        )
        return self.dist if same else None


class _Evaluation(NamedTuple):
    residuals: list[np.ndarray]  # acceleration (T, n), final (m,), collision (C, k, T)
    equations: NormalEquations
    guard: _Guard | None


def _residuals(
    robot: RobotModel,
    data: pin.Data,
    problem: TrajectoryProblem,
    x: np.ndarray,
    known: KnotFrames | None = None,
) -> _Point:
    """Residuals and cost at the free knots ``x`` (T, n) [rad], without the normal equations.

    A trial step needs only its cost (and its collision residuals), so the derivatives are left
    to :func:`_linearize`, which is skipped for rejected and final steps. ``known``: the frames
    (and distances) at ``x``, already computed (:class:`KnotFrames`).
    """
    T, n = x.shape
    c, dt = problem.costs, problem.dt
    s_acc = _acceleration_scale(c, dt)
    r_acc = np.empty((T, n))
    np.subtract(x[1:], x[:-1], out=r_acc[1:])  # first differences, then second ones
    r_acc[0] = x[0] - problem.q_start
    r_acc[1:] -= r_acc[:-1].copy()
    r_acc[0] -= dt * problem.v_start
    r_acc *= s_acc
    q_prev = x[-2] if T > 1 else problem.q_start
    r_fin, J_fin = _final_terms(robot.model, data, robot.tcp_frame_id, problem, q_prev, x[-1])
    if T == 1:  # q_{T-1} is the fixed start
        J_fin = J_fin[:, n:]
    flat_acc = r_acc.ravel()
    cost = float(flat_acc @ flat_acc + r_fin @ r_fin)

    r_col = np.zeros((len(robot.capsules), len(problem.obstacle_radii), T))
    poses = dist = near = None
    if r_col.size and c.collision > 0.0:
        kin = batch_kinematics(robot)
        poses = known.poses if known is not None else kin.forward(x)
        dist = known.distances(problem) if known is not None else None
        if dist is None:
            dist = kin.capsule_distances(poses, problem.obstacles, problem.obstacle_radii)
        # the pairs with 1 - d / margin > -_GUARD, sorted by knot, and their residuals
        cap, obs, knot, r_near = near_pairs(
            dist.distance, float(c.collision_margin), _GUARD, math.sqrt(c.collision), r_col
        )
        if knot.size:
            near = (cap, obs, knot)
            cost += float(r_near @ r_near)
    return _Point(x, [r_acc, r_fin, r_col], cost, J_fin, poses, dist, near)


def _linearize(robot: RobotModel, problem: TrajectoryProblem, point: _Point) -> _Evaluation:
    """Normal equations and guard curvature at ``point`` (see :func:`_residuals`).

    The guard holds ``2 J^T J`` of each collision pair within ``(1 + _GUARD)`` margins;
    :func:`solve_trajectory` may add those of inactive pairs to the matrix (never to the cost).
    """
    T, n = point.x.shape
    c, dt = problem.costs, problem.dt
    r_acc, r_fin, r_col = point.residuals
    s_acc = _acceleration_scale(c, dt)
    grad = np.empty((T, n))  # D^T r_acc: r_t - 2 r_{t+1} + r_{t+2}, zero past the end
    grad[:] = r_acc
    grad[:-1] -= 2.0 * r_acc[1:]
    grad[:-2] += r_acc[2:]
    grad *= 2.0 * s_acc
    hessian = np.array(_acceleration_band(n, T, float(dt), float(c.acceleration), c.metric))

    J_fin = point.final_jacobian
    m = J_fin.shape[1]
    grad.reshape(-1)[-m:] += 2.0 * (J_fin.T @ r_fin)
    _add_block(hessian, 2.0 * (J_fin.T @ J_fin), n * T - m)

    guard = None
    if point.near is not None and point.poses is not None and point.dist is not None:
        kin = batch_kinematics(robot)
        cap, obs, knot = near = point.near
        margin = c.collision_margin
        s_col = math.sqrt(c.collision)
        r_near = r_col[near]
        J_col = (-s_col / margin) * kin.distance_gradients(
            point.poses, point.dist, problem.obstacles, near
        )
        first = np.concatenate(([0], np.flatnonzero(knot[1:] != knot[:-1]) + 1))
        rows = knot[first]  # the knots with near pairs, each once
        grad[rows] += np.add.reduceat(2.0 * r_near[:, None] * J_col, first, axis=0)
        i, j = _lower_triangle(n)
        outer = 2.0 * J_col[:, i] * J_col[:, j]  # (P, n (n + 1) / 2)
        flat = ((rows[:, None] * n + j) * (2 * n + 1) + (i - j)).ravel()  # _band_memory's
        active = (r_near > 0.0)[:, None]
        _band_memory(hessian)[flat] += np.add.reduceat(outer * active, first, axis=0).ravel()
        guard = _Guard(near, outer, first, flat)
    return _Evaluation(
        point.residuals, NormalEquations(hessian, grad.reshape(-1), point.cost), guard
    )


def _evaluate(
    robot: RobotModel, data: pin.Data, problem: TrajectoryProblem, x: np.ndarray
) -> _Evaluation:
    """Residuals, normal equations and guard curvature at the free knots ``x`` (T, n) [rad]."""
    return _linearize(robot, problem, _residuals(robot, data, problem, x))


def _solve_band(band: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``x`` with ``A x = rhs`` for ``A`` in lower band storage; ``band`` and ``rhs`` are consumed.

    LAPACK's ``dpbsv`` called directly: what ``scipy.linalg.solveh_banded(band, rhs, lower=True,
    overwrite_ab=True, overwrite_b=True, check_finite=False)`` calls, without its ~20 us of
    checks per call (the same result to the bit).

    Raises:
        LinAlgError: the matrix is not positive definite.
    """
    _, x, info = _dpbsv(band, rhs, lower=1, overwrite_ab=1, overwrite_b=1)
    if info > 0:
        raise LinAlgError(f"{info}th leading minor not positive definite")
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal pbsv")
    return x


def _free_knots(robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    shape = (problem.steps + 1, robot.model.nq)
    if q.shape != shape:
        raise SolverError(f"trajectory of shape {q.shape}; expected {shape}", problem)
    return q[1:]


def build_normal_equations(
    robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray
) -> NormalEquations:
    """Gauss-Newton normal equations of ``problem`` at the trajectory ``q`` (pure).

    Args:
        robot: the arm.
        problem: the optimization problem.
        q: trajectory, shape (T + 1, 7) [rad]; row 0 is ignored (the start is ``problem.q_start``).

    Returns:
        The banded ``2 J^T J``, the gradient ``2 J^T r`` and the cost (module docstring).
    """
    x = _free_knots(robot, problem, q)
    return _evaluate(robot, robot.model.createData(), problem, x).equations


def trajectory_residuals(
    robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray
) -> np.ndarray:
    """The stacked residual vector r with ``cost = r . r``, for inspection and tests (pure).

    Order: acceleration (T x n, knot-major), final position (3), final joint velocity (n), final
    axis (3), final axis rate (3), collision (capsules x obstacles x T, zeros when inactive).
    """
    ev = _evaluate(robot, robot.model.createData(), problem, _free_knots(robot, problem, q))
    return np.concatenate([r.ravel() for r in ev.residuals])


def _initial_guess(problem: TrajectoryProblem) -> np.ndarray:
    """All knots at the start (the first Gauss-Newton step is then a min-acceleration reach)."""
    return np.tile(problem.q_start, (problem.steps + 1, 1))


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

    Each iteration is one banded Cholesky solve of ``(H + lambda I) dx = -g`` and one cost
    evaluation at ``x + dx``, so an iteration has a fixed price, as replanning needs (the normal
    equations at ``x + dx`` are built only when another iteration uses them). A step that
    does not increase the cost is taken and lambda shrinks 10x (down to ``damping``). A step that
    does is retried: if it brought collision pairs (within 1.25 margins, inactive at ``x``) into
    the margin, their ``2 J^T J`` is added to the matrix, the curvature Gauss-Newton cannot see
    while a pair is inactive (solutions hug the margin, so this is the usual cause), and it stays
    in the matrix for the rest of the solve whenever such a pair is inactive (otherwise the next
    step pushes the same pairs in again: measured on warm-started replanning, it more than
    halves the steps that need 4 or more iterations); otherwise lambda grows 10x. lambda starts
    at ``max(damping, 1)``, which spares the first rejections when an obstacle appears on a warm
    start. The solve stops when an accepted step lowers the
    cost by less than ``tolerance`` relative, when a step is below ``tolerance`` [rad] in every
    joint, or after ``max_iterations`` iterations.

    Args:
        robot: the arm.
        problem: the optimization problem.
        q_init: initial trajectory, shape (T + 1, 7) [rad] (row 0 is replaced by the start), e.g.
            :func:`shift_warm_start` of the previous solution; default: all knots at the start.
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
    x = _free_knots(robot, problem, _initial_guess(problem) if q_init is None else q_init)
    if init_frames is not None and init_frames.poses.position.shape[2] != len(x):
        init_frames = None
    point = _residuals(robot, data, problem, x, init_frames)
    if not math.isfinite(point.cost):
        raise SolverError(f"non-finite trajectory cost {point.cost} at the initial guess", problem)
    lam = max(damping, _INITIAL_DAMPING)
    converged, iterations = False, 0
    woken = np.zeros(point.residuals[2].shape, dtype=bool)  # pairs a rejected step pushed in
    current: _Evaluation | None = None  # the normal equations at point, made when needed
    while iterations < max_iterations and not converged:
        iterations += 1
        if current is None:
            current = _linearize(robot, problem, point)
        band = np.array(current.equations.hessian)
        guard = current.guard
        r_col = current.residuals[2]
        if guard is not None:
            guarded = woken[guard.pairs] & (r_col[guard.pairs] == 0.0)
            if guarded.any():
                _band_memory(band)[guard.flat] += guard.curvature(guarded)
        band[0] += lam
        try:
            step = _solve_band(band, -current.equations.gradient)
        except (LinAlgError, ValueError) as e:
            raise SolverError(f"Gauss-Newton Cholesky failed: {e}", problem) from e
        step = step.reshape(x.shape)
        trial = _residuals(robot, data, problem, point.x + step)
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
            pushed_in = False
            if guard is not None:  # inactive pairs that the rejected step made active
                newly = trial.residuals[2][guard.pairs] > 0.0
                newly &= r_col[guard.pairs] == 0.0
                newly &= ~woken[guard.pairs]
                pushed_in = bool(newly.any())
                woken[tuple(index[newly] for index in guard.pairs)] = True
            if not pushed_in:
                lam *= 10.0
    frames = None
    if point.poses is not None:
        frames = KnotFrames(point.poses, point.dist, problem.obstacles, problem.obstacle_radii)
    return TrajectorySolution(
        np.vstack([problem.q_start, point.x]), point.cost, iterations, converged, frames
    )


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
    """The authors' solver: ``optNewton`` of their framework (``Optim/optimization.cpp``).

    Damped Gauss-Newton steps ``Delta = -(H + lambda I)^-1 g`` (the same banded normal equations
    as :func:`solve_trajectory`), capped at ``max_step`` in every joint, with a backtracking line
    search (step factor alpha, x0.1 after a rejected trial, square-rooted after an accepted one;
    lambda halves after every accepted full step). It stops *without an update* when the step is
    below ``stop_tolerance / 10`` in every joint (so most warm-started replans change nothing),
    and after an update when it was below ``stop_tolerance``, after ``max_iterations`` steps or
    ``max_evaluations`` cost evaluations. ``lambda`` starts at ``damping`` (the original's 1e-3).

    Returns:
        The trajectory; ``converged`` tells whether a tolerance, not a limit, stopped it.

    Raises:
        SolverError: if the cost is not finite at the start or the factorization fails.
    """
    data = robot.model.createData()
    x = _free_knots(robot, problem, _initial_guess(problem) if q_init is None else q_init)
    current = _evaluate(robot, data, problem, x)
    fx = current.equations.cost
    if not math.isfinite(fx):
        raise SolverError(f"non-finite trajectory cost {fx} at the initial guess", problem)
    lam, alpha, evaluations, iterations, converged = damping, 1.0, 1, 0, False
    while True:
        iterations += 1
        band = np.array(current.equations.hessian)
        band[0] += lam
        try:
            delta = solveh_banded(band, -current.equations.gradient, lower=True, check_finite=False)
        except (LinAlgError, ValueError) as e:
            raise SolverError(f"Newton Cholesky failed: {e}", problem) from e
        delta = delta.reshape(x.shape)
        size = float(np.max(np.abs(delta)))
        if max_step > 0.0 and size > max_step:
            delta *= max_step / size
            size = max_step
        if lam < 2.0 and size < 0.1 * stop_tolerance:  # the lazy stop: no update
            converged = True
            break
        while True:  # line search
            trial = x + alpha * delta
            point = _residuals(robot, data, problem, trial)
            evaluations += 1
            if math.isfinite(point.cost) and point.cost <= fx:
                x, fx = trial, point.cost
                current = _linearize(robot, problem, point)
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


def shift_warm_start(solution_q: np.ndarray, steps_new: int) -> np.ndarray:
    """Warm start for the next replanning step (CR): drop the first knot, keep ``steps_new``.

    Args:
        solution_q: previous solution, shape (T + 1, 7) [rad].
        steps_new: the next horizon T'; rows past the old end repeat the old final knot.

    Returns:
        Initial trajectory, shape (T' + 1, 7) [rad]; row 0 (the old q_1) stands for the start.
    """
    if int(steps_new) != steps_new or steps_new < 1:
        raise ConfigError.invalid("steps_new", steps_new, "an integer >= 1")
    rest = np.asarray(solution_q, dtype=float)[1:]
    if len(rest) == 0:
        raise ConfigError.invalid("solution_q rows", 1, ">= 2")
    index = np.minimum(np.arange(steps_new + 1), len(rest) - 1)
    return rest[index]
