"""Compiled (Numba) inner loop of the operational-space controller: Eq. 4-6 in one call.

:func:`normal_equations` assembles ``A q_ddot = b`` of :mod:`amex.control.osc` (the weighted
tasks of Eq. 5 with the PD targets of Eq. 6 and the regularizer H of Eq. 4) and
:func:`cholesky_solve` solves it. The controller's constants travel as one float64 vector
at named offsets (:func:`pack_params`, :func:`params_dtype`). Compiled without ``fastmath``: IEEE
operations in program order, so results are bit-for-bit reproducible across runs and worker
counts. Why one compiled call, and what it costs: docs/controller.md.
"""

from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np

from amex.core.types import PD

_F8 = np.float64


#: The scalar fields of the controller's constants, in the order of :func:`params_dtype`; then
#: ``hdiag`` (n) and ``q_rest`` (n). The compiled kernels read the packed vector at these offsets.
PARAM_SCALARS = (
    "pos_kp",  # position task (Eq. 6, first row of Eq. 5)
    "pos_kd",
    "pos_weight",
    "axis_kp",  # axis task (second row)
    "axis_kd",
    "axis_weight",
    "damping_velocity",  # -weight * Kd of the damping task (times v)
    "damping_posture",  # weight * Kp of the damping task (times q_rest - q)
    "joint_kp",  # joint task (CR's joint targets)
    "joint_kd",
    "joint_weight",
    "col_kp",  # collision task (third row; target 0 penetration)
    "col_kd",
    "col_weight",
    "drift",  # 1: subtract the drift J_dot v of the TCP tasks (the original: 0, no drift term)
)
(
    POS_KP, POS_KD, POS_WEIGHT, AXIS_KP, AXIS_KD, AXIS_WEIGHT, DAMPING_VELOCITY, DAMPING_POSTURE,
    JOINT_KP, JOINT_KD, JOINT_WEIGHT, COL_KP, COL_KD, COL_WEIGHT, DRIFT,
) = range(len(PARAM_SCALARS))  # fmt: skip
HDIAG = len(PARAM_SCALARS)  # diagonal of H (Eq. 4) plus the damping task's weight, n values


@lru_cache(maxsize=8)
def params_dtype(n: int) -> np.dtype:
    """Named fields over the packed constants of an n-joint controller (:func:`pack_params`).

    Every field is float64, so ``params.view(params_dtype(n))[0]`` names the packed vector's
    entries without a copy: the scalars of :data:`PARAM_SCALARS`, then ``hdiag`` (n,) and
    ``q_rest`` (n,), the damping task's posture [rad].
    """
    fields = [(name, _F8) for name in PARAM_SCALARS]
    return np.dtype([*fields, ("hdiag", _F8, (n,)), ("q_rest", _F8, (n,))])


def pack_params(
    pos: PD,
    dir_: PD,
    joint: PD,
    col: PD,
    damping: PD,
    drift: bool,
    hdiag: np.ndarray,
    q_rest: np.ndarray,
) -> np.ndarray:
    """The controller's gains, regularizer diagonal and rest posture, packed, shape (15 + 2n,).

    A plain float64 vector (a compiled call unboxes it faster than a record); the kernels read
    it at the offsets :data:`POS_KP` ... :data:`HDIAG`, and :func:`params_dtype` names them.
    """
    n = len(hdiag)
    params = np.zeros(HDIAG + 2 * n)
    p = params.view(params_dtype(n))[0]
    p["pos_kp"], p["pos_kd"], p["pos_weight"] = pos.kp, pos.kd, pos.weight
    p["axis_kp"], p["axis_kd"], p["axis_weight"] = dir_.kp, dir_.kd, dir_.weight
    p["damping_velocity"] = -damping.weight * damping.kd
    p["damping_posture"] = damping.weight * damping.kp
    p["joint_kp"], p["joint_kd"], p["joint_weight"] = joint.kp, joint.kd, joint.weight
    p["col_kp"], p["col_kd"], p["col_weight"] = col.kp, col.kd, col.weight
    p["drift"] = 1.0 if drift else 0.0
    p["hdiag"], p["q_rest"] = hdiag, q_rest
    return params


def targets_size(n: int) -> int:
    """Length of the packed command targets of an n-joint controller (:func:`pack_targets`)."""
    return 2 + 12 + 2 * n


def pack_targets(
    out: np.ndarray,
    ty: np.ndarray | None,
    tyd: np.ndarray | None,
    tq: np.ndarray | None,
    tqd: np.ndarray | None,
) -> None:
    """Pack a command's targets into ``out`` (:func:`targets_size`) for :func:`normal_equations`.

    Layout: ``[has_y, has_q, y* (6), y_dot* (6), q* (n), q_dot* (n)]``; an absent target is a 0
    flag (its values are then not read), an absent velocity is zero.
    """
    n = (out.shape[0] - 14) // 2
    out[:] = 0.0
    if ty is not None:
        out[0] = 1.0
        out[2:8] = ty
        if tyd is not None:
            out[8:14] = tyd
    if tq is not None:
        out[1] = 1.0
        out[14 : 14 + n] = tq
        if tqd is not None:
            out[14 + n :] = tqd


@numba.njit(cache=True)
def normal_equations(  # per-step inputs as they come (nothing copied), constants in one record
    ws: np.ndarray,
    J: np.ndarray,
    v: np.ndarray,
    q: np.ndarray,
    tcp_pose: np.ndarray,
    drift: np.ndarray,
    targets: np.ndarray,
    col: np.ndarray,
    params: np.ndarray,
) -> None:
    """Fill ``A = ws[:n]`` (n x n) and ``b = ws[n]`` with the normal equations of Eq. 4-6, in place.

    Args:
        ws: output (n + 1, n): A in the first n rows, b in the last, overwritten.
        J: TCP Jacobian (6, n), LOCAL_WORLD_ALIGNED rows (linear, angular).
        v: joint velocities (n,) [rad/s].
        q: joint positions (n,) [rad].
        tcp_pose: TCP pose (4, 4); column 3 is the position, column 2 the z-axis.
        drift: TCP classical acceleration at q_ddot = 0 (6,) (``J_dot v``).
        targets: the command, packed by :func:`pack_targets`: the TCP tasks with y* and y_dot*
            if ``has_y``, the joint task with q* and q_dot* if ``has_q``.
        col: the collision task ``(phi_col, J_col)`` (1 + n,); active when phi_col > 0.
        params: the controller's constants, packed by :func:`pack_params`.
    """
    p = params
    n = v.shape[0]
    A = ws[:n]
    b = ws[n]
    for i in range(n):
        for j in range(n):
            A[i, j] = 0.0
        A[i, i] = p[HDIAG + i]
        b[i] = p[DAMPING_VELOCITY] * v[i]
    if targets[0] != 0.0:
        _add_tcp_tasks(A, b, J, v, tcp_pose, drift, targets[2:8], targets[8:14], p)
    if p[DAMPING_POSTURE] != 0.0:
        for i in range(n):
            b[i] += p[DAMPING_POSTURE] * (p[HDIAG + n + i] - q[i])
    if targets[1] != 0.0:
        tq, tqd = targets[14 : 14 + n], targets[14 + n : 14 + 2 * n]
        c = p[JOINT_WEIGHT]
        for i in range(n):
            A[i, i] += c
            b[i] += c * (p[JOINT_KP] * (tq[i] - q[i]) + p[JOINT_KD] * (tqd[i] - v[i]))
    if col[0] > 0.0:
        _add_collision_task(A, b, v, col[0], col[1:], p)


@numba.njit(cache=True)
def _tcp_targets(
    J: np.ndarray,
    v: np.ndarray,
    tcp_pose: np.ndarray,
    drift: np.ndarray,
    ty: np.ndarray,
    tyd: np.ndarray,
    p: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``rho`` (6,) and the axis block ``W_a`` (3, 3) of the position and axis tasks.

    ``rho``: the weighted Eq. 6 targets minus the drift, the axis rows mapped back through
    ``T_a = -[z]x J_w`` (``T_a^T s = J_w^T (z x s)``); ``W_a = c_axis (I - z z^T)``, so that
    ``T_a^T T_a = J_w^T W_a J_w / c_axis``.
    """
    n = v.shape[0]
    kp, kd, wp = p[POS_KP], p[POS_KD], p[POS_WEIGHT]
    kpa, kda, wa = p[AXIS_KP], p[AXIS_KD], p[AXIS_WEIGHT]
    tw = np.empty(6)
    for r in range(6):
        acc = 0.0
        for j in range(n):
            acc += J[r, j] * v[j]
        tw[r] = acc
    px, py, pz = tcp_pose[0, 3], tcp_pose[1, 3], tcp_pose[2, 3]
    zx, zy, zz = tcp_pose[0, 2], tcp_pose[1, 2], tcp_pose[2, 2]
    wx, wy, wz = tw[3], tw[4], tw[5]
    bx, by, bz = drift[3], drift[4], drift[5]
    # z_dot = w x z and its drift z_ddot|_(q_ddot=0) = alpha x z + w x z_dot (AxisMap)
    dx, dy, dz = wy * zz - wz * zy, wz * zx - wx * zz, wx * zy - wy * zx
    ex = by * zz - bz * zy + wy * dz - wz * dy
    ey = bz * zx - bx * zz + wz * dx - wx * dz
    ez = bx * zy - by * zx + wx * dy - wy * dx
    d0, d1, d2 = drift[0], drift[1], drift[2]
    if p[DRIFT] == 0.0:  # the original: no drift term
        ex = ey = ez = d0 = d1 = d2 = 0.0
    # Eq. 6 minus the drift: the task accelerations the joint accelerations must produce
    rho = np.empty(6)
    rho[0] = wp * (kp * (ty[0] - px) + kd * (tyd[0] - tw[0]) - d0)
    rho[1] = wp * (kp * (ty[1] - py) + kd * (tyd[1] - tw[1]) - d1)
    rho[2] = wp * (kp * (ty[2] - pz) + kd * (tyd[2] - tw[2]) - d2)
    sx = kpa * (ty[3] - zx) + kda * (tyd[3] - dx) - ex
    sy = kpa * (ty[4] - zy) + kda * (tyd[4] - dy) - ey
    sz = kpa * (ty[5] - zz) + kda * (tyd[5] - dz) - ez
    rho[3] = wa * (zy * sz - zz * sy)
    rho[4] = wa * (zz * sx - zx * sz)
    rho[5] = wa * (zx * sy - zy * sx)
    W = np.empty((3, 3))
    W[0, 0], W[1, 1], W[2, 2] = wa * (1.0 - zx * zx), wa * (1.0 - zy * zy), wa * (1.0 - zz * zz)
    W[0, 1] = W[1, 0] = -wa * zx * zy
    W[0, 2] = W[2, 0] = -wa * zx * zz
    W[1, 2] = W[2, 1] = -wa * zy * zz
    return rho, W


@numba.njit(cache=True)
def _add_tcp_tasks(
    A: np.ndarray,
    b: np.ndarray,
    J: np.ndarray,
    v: np.ndarray,
    tcp_pose: np.ndarray,
    drift: np.ndarray,
    ty: np.ndarray,
    tyd: np.ndarray,
    p: np.ndarray,
) -> None:
    """Add the position and axis tasks, ``A += J^T diag(c_pos I, W_a) J``, ``b += J^T rho``."""
    n = v.shape[0]
    wp = p[POS_WEIGHT]
    rho, W = _tcp_targets(J, v, tcp_pose, drift, ty, tyd, p)
    WJ = np.empty((3, n))  # axis block W_a J_w
    for r in range(3):
        for j in range(n):
            WJ[r, j] = W[r, 0] * J[3, j] + W[r, 1] * J[4, j] + W[r, 2] * J[5, j]
    for i in range(n):
        for j in range(i + 1):
            acc = wp * (J[0, i] * J[0, j] + J[1, i] * J[1, j] + J[2, i] * J[2, j])
            acc += J[3, i] * WJ[0, j] + J[4, i] * WJ[1, j] + J[5, i] * WJ[2, j]
            A[i, j] += acc
            if j != i:
                A[j, i] += acc
        acc = 0.0
        for r in range(6):
            acc += J[r, i] * rho[r]
        b[i] += acc


@numba.njit(cache=True)
def _add_collision_task(
    A: np.ndarray, b: np.ndarray, v: np.ndarray, col_phi: float, Jc: np.ndarray, p: np.ndarray
) -> None:
    """Add the collision task: target 0 penetration, drift neglected (CollisionMap); Jc (n,)."""
    n = v.shape[0]
    c = p[COL_WEIGHT]
    phid = 0.0
    for j in range(n):
        phid += Jc[j] * v[j]
    target = p[COL_KP] * (0.0 - col_phi) + p[COL_KD] * (0.0 - phid)
    for i in range(n):
        for j in range(n):
            A[i, j] += c * Jc[i] * Jc[j]
        b[i] += c * Jc[i] * target


@numba.njit(cache=True)
def cholesky_solve(A: np.ndarray, b: np.ndarray, x: np.ndarray) -> int:
    """Solve ``A x = b`` for symmetric positive definite A by Cholesky, A and b untouched.

    Returns:
        0 on success, else the 1-based index of the first non-positive pivot (LAPACK's
        ``info`` convention); ``x`` is then undefined.
    """
    return _cholesky_solve(A, b, x, np.zeros(A.shape))


@numba.njit(cache=True)
def _cholesky_solve(A: np.ndarray, b: np.ndarray, x: np.ndarray, L: np.ndarray) -> int:
    """:func:`cholesky_solve` with the work space ``L`` (n, n) of the factor (upper part unread)."""
    n = b.shape[0]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:  # also catches NaN
            return j + 1
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    for i in range(n):  # L z = b
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):  # L^T x = z
        s = x[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return 0


def workspace(n: int) -> np.ndarray:
    """The work space of :func:`osc_accelerations` for n joints: A, b, x and the factor L."""
    return np.zeros((2 * n + 2, n))


@numba.njit(cache=True)
def osc_accelerations(
    ws: np.ndarray,
    J: np.ndarray,
    v: np.ndarray,
    q: np.ndarray,
    tcp_pose: np.ndarray,
    drift: np.ndarray,
    targets: np.ndarray,
    col: np.ndarray,
    params: np.ndarray,
) -> int:
    """:func:`normal_equations` into ``ws`` (:func:`workspace`), then the Cholesky solve.

    ``ws`` rows: A (n), b (1), the solution x = q_ddot* (1), the factor L (n).

    Returns:
        the solve's ``info`` (0 on success).
    """
    normal_equations(ws, J, v, q, tcp_pose, drift, targets, col, params)
    n = v.shape[0]
    return _cholesky_solve(ws[:n], ws[n], ws[n + 1], ws[n + 2 :])


@numba.njit(cache=True)
def clip_into(out: np.ndarray, x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """``out = min(max(x, lo), hi)`` element-wise (NaN stays NaN), as :func:`clip_inplace`."""
    for i in range(x.shape[0]):
        xi = x[i]
        if xi < lo[i]:
            xi = lo[i]
        elif xi > hi[i]:
            xi = hi[i]
        out[i] = xi


@numba.njit(cache=True)
def clip_inplace(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """``x = min(max(x, lo), hi)`` element-wise, in place (NaN stays NaN)."""
    for i in range(x.shape[0]):
        if x[i] < lo[i]:
            x[i] = lo[i]
        elif x[i] > hi[i]:
            x[i] = hi[i]


@numba.njit(cache=True)
def euler_inplace(q: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float) -> None:
    """``q += dt v; v += dt a`` element-wise, in place (the kinematic simulation's step)."""
    for i in range(q.shape[0]):
        q[i] += dt * v[i]
        v[i] += dt * a[i]
