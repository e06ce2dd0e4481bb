"""Compiled (Numba) inner loop of the operational-space controller: Eq. 4-6 in one call.

:func:`normal_equations` assembles ``A q_ddot = b`` of :mod:`amex.control.osc` (the weighted
tasks of Eq. 5 with the PD targets of Eq. 6 and the regularizer H of Eq. 4) and
:func:`cholesky_solve` solves it. The controller's constants travel as one float64 vector
at named offsets (:mod:`amex.control.packing`). Compiled without ``fastmath``: IEEE
operations in program order, so results are bit-for-bit reproducible across runs and worker
counts. Why one compiled call, and what it costs: docs/controller.md.
"""

from __future__ import annotations

import numba
import numpy as np

from amex.control.packing import (
    AXIS_KD,
    AXIS_KP,
    AXIS_WEIGHT,
    COL_KD,
    COL_KP,
    COL_WEIGHT,
    DAMPING_POSTURE,
    DAMPING_VELOCITY,
    DRIFT,
    HDIAG,
    JOINT_KD,
    JOINT_KP,
    JOINT_WEIGHT,
    POS_KD,
    POS_KP,
    POS_WEIGHT,
)


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
