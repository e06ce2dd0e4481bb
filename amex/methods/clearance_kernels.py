"""Compiled (Numba) pair terms of :mod:`amex.methods.clearance`: gradients, rates and drifts.

One call per outer step computes, for every arm-obstacle pair, the formulas of
:mod:`amex.methods.clearance`'s module notes (the gradient ``n^T J_p``, the rate ``-n^T v_o``
and the drift ``d_ddot`` at ``q_ddot = 0``, exact on a capsule's cylinder and caps) from the
pairs' joints' placements, Jacobians and (local) velocities and accelerations. Compiled without
``fastmath`` (IEEE operations in program order: the same numbers on every run and worker).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _rot(R: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    for i in range(3):
        out[i] = R[i, 0] * x[0] + R[i, 1] * x[1] + R[i, 2] * x[2]


@numba.njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def pair_terms(
    rows: np.ndarray,
    rotation: np.ndarray,
    origin: np.ndarray,
    jacobian: np.ndarray,
    v_local: np.ndarray,
    a_local: np.ndarray,
    normal: np.ndarray,
    point: np.ndarray,
    center: np.ndarray,
    v_obstacle: np.ndarray,
    offset: np.ndarray,
    axis: np.ndarray,
    half: np.ndarray,
    drift: bool,
    gradient: np.ndarray,
    rate: np.ndarray,
    accel: np.ndarray,
) -> None:
    """Fill ``gradient`` (k, n), ``rate`` (k,) and, if ``drift``, ``accel`` (k,) in place.

    Longer than 80 lines on purpose: one compiled call per step, written statement for statement
    as its numpy oracle so that the two stay bit-identical and can be read side by side; split,
    each part would be another dispatch per step.

    Per pair i: ``rows[i]`` its joint's row in the per-joint arrays ``rotation`` (u, 3, 3),
    ``origin`` (u, 3), ``jacobian`` (u, 6, n, LOCAL_WORLD_ALIGNED), ``v_local`` and ``a_local``
    (u, 6: the joint's spatial velocity and acceleration at ``q_ddot = 0`` in its own frame,
    linear first); ``normal``, ``point`` (the arm's witness point), ``center`` and ``v_obstacle``
    (k, 3); its capsule's axis centre ``offset`` and direction ``axis`` (k, 3) in the joint frame
    and ``half`` length (k,).
    """
    k, n = gradient.shape
    r = np.empty(3)
    rxn = np.empty(3)
    tmp = np.empty(3)
    v_lin = np.empty(3)
    w = np.empty(3)
    a_lin = np.empty(3)
    alpha = np.empty(3)
    u = np.empty(3)
    p = np.empty(3)
    e = np.empty(3)
    e_dot = np.empty(3)
    u_dot = np.empty(3)
    m_dot = np.empty(3)
    a_point = np.empty(3)
    wr = np.empty(3)
    for i in range(k):
        j = rows[i]
        J = jacobian[j]
        for c in range(3):
            r[c] = point[i, c] - origin[j, c]
        _cross(r, normal[i], rxn)  # n^T (J_v - [r]x J_w) = n^T J_v + (r x n)^T J_w
        for col in range(n):
            g = 0.0
            for c in range(3):
                g += normal[i, c] * J[c, col] + rxn[c] * J[3 + c, col]
            gradient[i, col] = g
        rate[i] = -_dot(normal[i], v_obstacle[i])
        if not drift:
            continue
        R = rotation[j]
        _rot(R, v_local[j, :3], v_lin)
        _rot(R, v_local[j, 3:], w)
        _cross(v_local[j, 3:], v_local[j, :3], tmp)  # classical: a + w x v (local)
        for c in range(3):
            tmp[c] += a_local[j, c]
        _rot(R, tmp, a_lin)
        _rot(R, a_local[j, 3:], alpha)
        _rot(R, offset[i], tmp)
        _rot(R, axis[i], u)
        for c in range(3):
            tmp[c] += origin[j, c]  # the axis centre in the world
        s = 0.0
        for c in range(3):
            s += (center[i, c] - tmp[c]) * u[c]
        h = half[i]
        cyl = h > 0.0 and abs(s) < h
        if not cyl:
            s = math.copysign(h, s)
        for c in range(3):
            p[c] = tmp[c] + s * u[c]
            r[c] = p[c] - origin[j, c]
        _cross(w, r, wr)
        _cross(alpha, r, a_point)
        _cross(w, wr, tmp)
        for c in range(3):
            a_point[c] += a_lin[c] + tmp[c]
            e[c] = p[c] - center[i, c]
            e_dot[c] = v_lin[c] + wr[c] - v_obstacle[i, c]
        _cross(w, u, u_dot)
        ue_dot = 0.0
        if cyl:
            eu = _dot(e, u)
            for c in range(3):
                e[c] -= eu * u[c]  # u . e = 0 on the cylinder
            ue_dot = _dot(u, e_dot) + _dot(u_dot, e)
            for c in range(3):
                m_dot[c] = e_dot[c] - ue_dot * u[c]
        else:
            for c in range(3):
                m_dot[c] = e_dot[c]
        rho = max(math.sqrt(_dot(e, e)), 1e-12)
        along = _dot(e, m_dot) / rho
        nm = _dot(e, a_point) / rho
        if cyl:
            nm -= 2.0 * (_dot(e, u_dot) / rho) * ue_dot
        accel[i] = (_dot(m_dot, m_dot) - along * along) / rho + nm
