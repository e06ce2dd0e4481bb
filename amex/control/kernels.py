"""Compiled (Numba) inner loop of the operational-space controller: Eq. 4-6 in one call.

At 1 kHz every numpy call costs about a microsecond of interpreter and dispatch overhead, and
the normal equations of Eq. 4 took about 25 of them (22 us of a 50 us step). Here they are
assembled and solved in a single compiled call (~2 us): one loop nest over the 6 x 7 TCP
Jacobian, a 7 x 7 Cholesky factorization and two triangular solves. The arithmetic is exactly the
fused form documented in :meth:`amex.control.osc.OperationalSpaceController.build_objective`;
:meth:`~amex.control.osc.OperationalSpaceController.build_objective_reference` (numpy, task map
by task map) is the test oracle. Compiled without ``fastmath``: IEEE operations in program
order, so results are bit-for-bit reproducible across runs and worker counts.

The parameter vector ``prm`` (built once per controller, :func:`pack_gains`) holds, in order:

======  =================================================================
index   meaning
======  =================================================================
0-2     position task Kp, Kd, weight (Eq. 6, first row of Eq. 5)
3-5     axis task Kp, Kd, weight (second row)
6       (unused: the diagonal is the ``hdiag`` argument)
7       ``-weight * Kd`` of the damping task (times v)
8       ``weight * Kp`` of the damping task (times q_rest - q)
9-11    joint task Kp, Kd, weight (CR's joint targets)
12-14   collision task Kp, Kd, weight (third row; target 0 penetration)
15      1: subtract the drift ``J_dot v`` of the TCP tasks; 0: leave it out (the original)
======  =================================================================

``hdiag`` (n,) is the diagonal of the regularizer ``H`` of Eq. 4 plus the damping task's weight
(its Jacobian is I).
"""

from __future__ import annotations

import numba
import numpy as np

N_PARAMS = 16


def pack_gains(pos, dir_, joint, col, damping, reg: float, drift: bool = True) -> np.ndarray:
    """The ``prm`` vector of the module table from the controller's PD gains."""
    return np.array(
        [
            pos.kp,
            pos.kd,
            pos.weight,
            dir_.kp,
            dir_.kd,
            dir_.weight,
            reg + damping.weight,
            -damping.weight * damping.kd,
            damping.weight * damping.kp,
            joint.kp,
            joint.kd,
            joint.weight,
            col.kp,
            col.kd,
            col.weight,
            1.0 if drift else 0.0,
        ],
        dtype=np.float64,
    )


@numba.njit(cache=True)
def normal_equations(  # a flat signature keeps the compiled call cheap
    A: np.ndarray,
    b: np.ndarray,
    J: np.ndarray,
    v: np.ndarray,
    q: np.ndarray,
    H: np.ndarray,
    drift: np.ndarray,
    task_on: bool,
    ty: np.ndarray,
    tyd: np.ndarray,
    joint_on: bool,
    tq: np.ndarray,
    tqd: np.ndarray,
    q_rest: np.ndarray,
    col_phi: float,
    Jc: np.ndarray,
    prm: np.ndarray,
    hdiag: np.ndarray,
) -> None:
    """Fill ``A`` (n x n) and ``b`` (n,) with the normal equations of Eq. 4-6, in place.

    Args:
        A: output (n, n), overwritten.
        b: output (n,), overwritten.
        J: TCP Jacobian (6, n), LOCAL_WORLD_ALIGNED rows (linear, angular).
        v: joint velocities (n,) [rad/s].
        q: joint positions (n,) [rad].
        H: TCP pose (4, 4); column 3 is the position, column 2 the z-axis.
        drift: TCP classical acceleration at q_ddot = 0 (6,) (``J_dot v``).
        task_on: whether the position/axis tasks are active (a task-space command).
        ty: task target y* (6,) (position, axis); read when ``task_on``.
        tyd: its velocity y_dot* (6,); read when ``task_on``.
        joint_on: whether the joint task is active (a joint-space command).
        tq: joint target q* (n,); read when ``joint_on``.
        tqd: its velocity q_dot* (n,); read when ``joint_on``.
        q_rest: posture of the damping task (n,).
        col_phi: collision penetration phi_col (the task is active when > 0).
        Jc: its Jacobian (1, n).
        prm: gains (module table).
        hdiag: diagonal of H plus the damping weight (n,).
    """
    n = v.shape[0]
    for i in range(n):
        for j in range(n):
            A[i, j] = 0.0
        A[i, i] = hdiag[i]
        b[i] = prm[7] * v[i]
    if task_on:
        kp, kd, wp = prm[0], prm[1], prm[2]
        kpa, kda, wa = prm[3], prm[4], prm[5]
        tw = np.empty(6)
        for r in range(6):
            acc = 0.0
            for j in range(n):
                acc += J[r, j] * v[j]
            tw[r] = acc
        px, py, pz = H[0, 3], H[1, 3], H[2, 3]
        zx, zy, zz = H[0, 2], H[1, 2], H[2, 2]
        wx, wy, wz = tw[3], tw[4], tw[5]
        bx, by, bz = drift[3], drift[4], drift[5]
        # z_dot = w x z and its drift z_ddot|_(q_ddot=0) = alpha x z + w x z_dot (AxisMap)
        dx, dy, dz = wy * zz - wz * zy, wz * zx - wx * zz, wx * zy - wy * zx
        ex = by * zz - bz * zy + wy * dz - wz * dy
        ey = bz * zx - bx * zz + wz * dx - wx * dz
        ez = bx * zy - by * zx + wx * dy - wy * dx
        d0, d1, d2 = drift[0], drift[1], drift[2]
        if prm[15] == 0.0:  # the original: no drift term
            ex = ey = ez = d0 = d1 = d2 = 0.0
        # Eq. 6 minus the drift: the task accelerations the joint accelerations must produce
        rx = wp * (kp * (ty[0] - px) + kd * (tyd[0] - tw[0]) - d0)
        ry = wp * (kp * (ty[1] - py) + kd * (tyd[1] - tw[1]) - d1)
        rz = wp * (kp * (ty[2] - pz) + kd * (tyd[2] - tw[2]) - d2)
        sx = kpa * (ty[3] - zx) + kda * (tyd[3] - dx) - ex
        sy = kpa * (ty[4] - zy) + kda * (tyd[4] - dy) - ey
        sz = kpa * (ty[5] - zz) + kda * (tyd[5] - dz) - ez
        # axis rows T_a = -[z]x J_w: T_a^T s = J_w^T (z x s), T_a^T T_a = J_w^T (I - zz^T) J_w
        rho = np.empty(6)
        rho[0], rho[1], rho[2] = rx, ry, rz
        rho[3] = wa * (zy * sz - zz * sy)
        rho[4] = wa * (zz * sx - zx * sz)
        rho[5] = wa * (zx * sy - zy * sx)
        W = np.empty((3, 3))
        W[0, 0], W[1, 1], W[2, 2] = wa * (1.0 - zx * zx), wa * (1.0 - zy * zy), wa * (1.0 - zz * zz)
        W[0, 1] = W[1, 0] = -wa * zx * zy
        W[0, 2] = W[2, 0] = -wa * zx * zz
        W[1, 2] = W[2, 1] = -wa * zy * zz
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
    if prm[8] != 0.0:
        for i in range(n):
            b[i] += prm[8] * (q_rest[i] - q[i])
    if joint_on:
        kp, kd, c = prm[9], prm[10], prm[11]
        for i in range(n):
            A[i, i] += c
            b[i] += c * (kp * (tq[i] - q[i]) + kd * (tqd[i] - v[i]))
    if col_phi > 0.0:
        kp, kd, c = prm[12], prm[13], prm[14]
        phid = 0.0
        for j in range(n):
            phid += Jc[0, j] * v[j]
        target = kp * (0.0 - col_phi) + kd * (0.0 - phid)  # drift neglected (CollisionMap)
        for i in range(n):
            for j in range(n):
                A[i, j] += c * Jc[0, i] * Jc[0, j]
            b[i] += c * Jc[0, i] * target


@numba.njit(cache=True)
def cholesky_solve(A: np.ndarray, b: np.ndarray, x: np.ndarray) -> int:
    """Solve ``A x = b`` for symmetric positive definite A by Cholesky, A and b untouched.

    Returns:
        0 on success, else the 1-based index of the first non-positive pivot (LAPACK's
        ``info`` convention); ``x`` is then undefined.
    """
    n = b.shape[0]
    L = np.zeros((n, n))
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
def osc_accelerations(A: np.ndarray, b: np.ndarray, x: np.ndarray, *args) -> int:
    """:func:`normal_equations` (``A``, ``b`` and ``args``) then :func:`cholesky_solve` into ``x``.

    Returns:
        the solve's ``info`` (0 on success).
    """
    normal_equations(A, b, *args)
    return cholesky_solve(A, b, x)


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
