"""Compiled (Numba) AMEX update: Algorithm 1, steps 2-4 (Eq. 7, 8, 9), in one call.

:func:`amex_update` is :meth:`amex.methods.amex.AMEX.update_reference` (the numpy oracle)
operation for operation: the same guards, the same order of floating-point operations, and the
same BLAS calls where the oracle makes them (``np.dot`` of two vectors, the 3 x w spline-weight
product), so that both give the same numbers. The state it advances lives in two arrays that
:class:`~amex.methods.amex.AMEX` owns (:data:`~amex.methods.amex_layout.STATE_FIELDS`; the
plan's offset p, slope q and the previous y as rows of one (3, m) array), the constants in a
third (:data:`~amex.methods.amex_layout.CONSTANTS`).
Compiled without ``fastmath``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from amex.methods.amex_layout import N_CONSTANTS


@numba.njit(cache=True)
def _weights(knots: np.ndarray, n_basis: int, s: float) -> tuple:
    """``QuadraticBSpline.weights``: ``(i, b0, b1, b2, d0, d1, d2)`` at phase s."""
    u = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
    mu = int(np.searchsorted(knots, u, side="right")) - 1  # t[mu] <= u < t[mu + 1]
    last = n_basis - 1
    if mu > last:  # u == 1: the last non-empty span
        mu = last
    a, b, c, d = knots[mu - 1], knots[mu], knots[mu + 1], knots[mu + 2]
    l1 = u - b
    r1 = c - u
    h = c - b
    tmp0 = r1 / (h * (c - a))
    tmp1 = l1 / (h * (d - b))
    alpha = 2.0 * tmp0
    beta = 2.0 * tmp1
    return (
        mu - 2,
        r1 * tmp0,
        (u - a) * tmp0 + (d - u) * tmp1,
        l1 * tmp1,
        -alpha,
        alpha - beta,
        beta,
    )


@numba.njit(cache=True)
def _norm(a: np.ndarray) -> float:
    """``sqrt(a . a)`` by BLAS ``ddot``, as the oracle's ``math.sqrt(np.dot(a, a))``."""
    return math.sqrt(np.dot(a, a))


@numba.njit(cache=True)
def _finite(a: np.ndarray) -> bool:
    for i in range(a.shape[0]):  # noqa: SIM110 (compiled: a plain loop)
        if not math.isfinite(a[i]):
            return False
    return True


@numba.njit(cache=True)
def amex_update(
    y: np.ndarray,
    g: np.ndarray,
    y_star: np.ndarray,
    yd_star: np.ndarray,
    state: np.ndarray,
    vectors: np.ndarray,
    C: np.ndarray,
    knots: np.ndarray,
    consts: np.ndarray,
) -> int:
    """One outer step of Algorithm 1 for task state y and goal g, shapes (m,); in place.

    Longer than 80 lines on purpose: one compiled call per step, written statement for statement
    as its numpy oracle so that the two stay bit-identical and can be read side by side; split,
    each part would be another dispatch per step.

    Eq. 8 advances the phase s (the guarded factors delta_g, delta_y; the warm-up steps add
    Delta s_ref), Eq. 7 re-anchors the plan offset (p, q) so that tau_plan(s) = y and
    tau_plan(1) = g, Eq. 9 gives the target y* = y + step along the plan and y_dot* = step / dt;
    from s >= 1 - end_margin the final approach (module :mod:`amex.methods.amex`).

    Args:
        y: the measured task state, shape (m,).
        g: the goal, shape (m,).
        y_star: output y*, shape (m,).
        yd_star: output y_dot*, shape (m,).
        state: the scalars of :data:`~amex.methods.amex_layout.STATE_FIELDS`, advanced.
        vectors: rows p, q (the plan's offset) and y_prev, shape (3, m), advanced.
        C: tau_ref's control points, zero-padded for the weight window, shape (N + pad, m).
        knots: tau_ref's knot vector.
        consts: :data:`~amex.methods.amex_layout.CONSTANTS`, then g_ref (m).

    Returns:
        0; 1 or 2 if y or g holds a NaN or an infinity (nothing changed).
    """
    if not _finite(y):
        return 1
    if not _finite(g):
        return 2
    m = y.shape[0]
    ds_ref, warmup, rate_min, rate_max = consts[0], consts[1], consts[2], consts[3]
    eps_goal, eps_step, eps_tangent = consts[4], consts[5], consts[6]
    end_margin, end_distance, approach_rate = consts[7], consts[8], consts[9]
    peak_speed, dt, secant, n_basis = consts[10], consts[11], consts[12], int(consts[13])
    g_ref = consts[N_CONSTANTS : N_CONSTANTS + m]
    p, q, y_prev = vectors[0], vectors[1], vectors[2]
    # Eq. 8 factors, guarded; computed every step for the log, used after the warm-up
    gy = g - y
    dist_goal = _norm(gy)
    delta_g = state[5] / dist_goal if dist_goal > eps_goal else rate_max
    delta_y = _norm(y - y_prev) / state[3] if state[3] > eps_step else 1.0
    k = state[1]
    state[1] = k + 1.0
    y_prev[:] = y
    state[6], state[7] = delta_g, delta_y
    if k == 0.0:
        s = 0.0
    elif state[2] != 0.0 or state[4] >= 1.0:
        s = 1.0
    else:
        rate = 1.0 if k <= warmup else delta_g * delta_y
        if rate_min > rate:  # Python's min(max(rate, rate_min), rate_max)
            rate = rate_min
        if rate_max < rate:
            rate = rate_max
        s = state[0] + ds_ref * rate
    if s >= 1.0 - end_margin:  # the final approach at s = 1
        state[0] = state[8] = 1.0
        state[2] = 1.0
        v = approach_rate * gy
        speed = _norm(v)
        if speed > peak_speed:
            v *= peak_speed / speed
            speed = peak_speed
        state[3] = speed * dt
        y_star[:] = y + dt * v
        yd_star[:] = v
        return 0
    state[0] = state[8] = s
    s_t = s + ds_ref
    if s_t > 1.0:
        s_t = 1.0
    state[4] = s_t  # the phase this step's command aims at
    i, w0, w1, w2, e0, e1, e2 = _weights(knots, n_basis, s)
    j, b0, b1, b2, _, _, _ = _weights(knots, n_basis, s_t)
    width = C.shape[0] - n_basis + 3
    W = np.zeros((3, width))  # rows: values at s_t, values at s, derivatives at s
    o = j - i
    W[0, o], W[0, o + 1], W[0, o + 2] = b0, b1, b2
    W[1, 0], W[1, 1], W[1, 2] = w0, w1, w2
    W[2, 0], W[2, 1], W[2, 2] = e0, e1, e2
    X = np.dot(W, C[i : i + width])  # tau_ref(s_t), tau_ref(s), tau_ref'(s)
    # Eq. 7 in closed form (WarpedSpline.anchor): tau_plan(1) = g and tau_plan(s) = y
    p[:] = g - g_ref
    q[:] = gy + X[1]
    q -= g_ref
    q *= 1.0 / (1.0 - s)
    r_t = g_ref - X[0]
    state[5] = _norm(r_t)  # delta_g's numerator, next step
    if state[5] <= end_distance:  # the reference has arrived: end the phase
        state[4] = 1.0
    # Eq. 9: along the warped plan, with the reference's progress
    if secant != 0.0:
        ref_step = X[0] - X[1]  # tau_ref(s_t) - tau_ref(s)
        length = _norm(ref_step)
        direction = (s_t - s) * q  # tau_plan(s_t) - tau_plan(s)
        direction += ref_step
    else:
        tangent = X[2]
        length = ds_ref * _norm(tangent)  # ds ||tau_ref'(s)||
        direction = tangent + q  # tau_plan'(s)
    norm_dir = _norm(direction)
    if not norm_dir > eps_tangent:
        if dist_goal > eps_goal:
            direction, norm_dir = gy, dist_goal
        else:
            length, norm_dir = 0.0, 1.0
    if length > dist_goal:  # never past the goal
        length = dist_goal
    state[3] = length
    step = direction * (length / norm_dir)
    y_star[:] = y + step
    yd_star[:] = step * (1.0 / dt)
    return 0
