"""Compiled (Numba) RMPflow step: every leaf pulled back and resolved in one call.

The leaves of :mod:`amex.methods.rmpflow_leaves`, with the formulas of
:meth:`amex.methods.rmpflow.RMPflow.resolve_leaves`, which stays the readable reference the tests
compare this kernel with.

Compiled without ``fastmath``: IEEE operations in program order, the same numbers on every run.
The resolve is a Cholesky solve of the summed metric (positive definite by the damping leaf's
constant metric); :func:`resolve` reports ``False`` when the factorization fails, and the caller
falls back to the pseudo-inverse.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _sigmoid(z: float) -> float:
    return 0.5 * (1.0 + math.tanh(0.5 * z))


@numba.njit(cache=True)
def _add_pullback(A, b, Jt, M, f, m):  # A += Jt^T M Jt, b += Jt^T M f for an (m, n) Jt
    n = A.shape[0]
    MJ = np.zeros((m, n))
    Mf = np.zeros(m)
    for i in range(m):
        for k in range(m):
            Mik = M[i, k]
            if Mik != 0.0:
                Mf[i] += Mik * f[k]
                for j in range(n):
                    MJ[i, j] += Mik * Jt[k, j]
    for r in range(n):
        acc = 0.0
        for i in range(m):
            acc += Jt[i, r] * Mf[i]
        b[r] += acc
        for c in range(n):
            s = 0.0
            for i in range(m):
                s += Jt[i, r] * MJ[i, c]
            A[r, c] += s


@numba.njit(cache=True)
def resolve(J, y, acc_drift, q, qd, goal, q_lo, q_hi, q_rest, distance, gradient, rate, drift,
            goal_p, axis_p, obstacle_p, limit_p, posture_p, damping_p, A, b, qdd):  # fmt: skip
    """Fill the summed metric ``A`` (n, n), force ``b`` (n,) and ``qdd`` (n,); True if solved.

    Longer than 80 lines on purpose: one compiled call per step, written statement for statement
    as its numpy oracle so that the two stay bit-identical and can be read side by side; split,
    each part would be another dispatch per step.

    ``goal_p``: gain, damping, softness, metric_max, metric_min, metric_length, metric_alpha,
    boost, boost_length; ``axis_p``: gain, damping, metric; ``obstacle_p``: margin, gain,
    gain_length, damping, damping_length, damping_eps, velocity_gate, radius, metric,
    metric_length, metric_eps; ``limit_p``: metric, metric_length, metric_eps, velocity_gate,
    damping, gain, gain_length, gain_eps; ``posture_p``: gain, damping, limit, metric;
    ``damping_p``: gain, metric, inertia (the leaves' arguments, in their order).
    """
    n = q.shape[0]
    A[:, :] = 0.0
    b[:] = 0.0
    # goal attractor on the TCP position
    Jp = J[:3]
    delta = goal[:3] - y[:3]
    dist = math.sqrt(delta[0] ** 2 + delta[1] ** 2 + delta[2] ** 2)
    xd = Jp @ qd
    gain, damping, soft, mmax, mmin, mlen, malpha, boost, blen = goal_p
    accel = gain * delta / (dist + soft) - damping * xd
    s = delta / max(dist, 0.1 * soft, 1e-12)
    alpha = (1.0 - malpha) * math.exp(-0.5 * (dist / mlen) ** 2) + malpha
    bb = 1.0 + (boost - 1.0) * math.exp(-0.5 * (dist / blen) ** 2)
    M = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            M[i, k] = bb * ((alpha * mmax if i == k else 0.0) + (1.0 - alpha) * mmin * s[i] * s[k])
    _add_pullback(A, b, Jp, M, accel - acc_drift[:3], 3)
    # axis attractor on the TCP z-axis: J_z = -[z]x J_w
    z = y[3:]
    Jw = J[3:]
    w = Jw @ qd
    Jz = np.empty((3, n))
    for j in range(n):
        Jz[0, j] = -(z[1] * Jw[2, j] - z[2] * Jw[1, j])
        Jz[1, j] = -(z[2] * Jw[0, j] - z[0] * Jw[2, j])
        Jz[2, j] = -(z[0] * Jw[1, j] - z[1] * Jw[0, j])
    zd = np.cross(w, z)
    z_drift = np.cross(acc_drift[3:], z) + np.cross(w, zd)
    ag, ad, am = axis_p
    f = ag * (goal[3:6] - z) - ad * zd - z_drift
    Ma = np.zeros((3, 3))
    for i in range(3):
        Ma[i, i] = am
    _add_pullback(A, b, Jz, Ma, f, 3)
    # obstacle leaves, one per pair
    margin, og, ogl, od, odl, odeps, ovg, orad, om, oml, omeps = obstacle_p
    for k in range(distance.shape[0]):
        G = gradient[k]
        dd = rate[k]
        for j in range(n):
            dd += G[j] * qd[j]
        x = max(distance[k] - margin, 0.0)
        gate = 1.0 - _sigmoid(dd / ovg)
        a = og * math.exp(-x / ogl) - gate * od * dd / (x / odl + odeps)
        m = gate * (om / (x / oml + omeps) * (1.0 - x / orad) ** 2) if x < orad else 0.0
        if m != 0.0:
            fk = m * (a - drift[k])
            for r in range(n):
                b[r] += G[r] * fk
                for c in range(n):
                    A[r, c] += m * G[r] * G[c]
    # joint limits, default configuration and joint damping (diagonal)
    lm, lml, lmeps, lvg, ld, lg, lgl, lgeps = limit_p
    pg, pd, plim, pm = posture_p
    dg, dm, dinertia = damping_p
    e = q - q_rest
    norm = math.sqrt(np.sum(e * e))
    scale = 1.0 if norm < plim else plim / norm
    speed = math.sqrt(np.sum(qd * qd))
    dmetric = dm * speed + dinertia
    for j in range(n):
        x_hi = max(q_hi[j] - q[j], 0.0)
        w_hi = (1.0 - _sigmoid(-qd[j] / lvg)) * lm / (x_hi / lml + lmeps)
        a_hi = lg / ((x_hi / lgl) ** 2 + lgeps) + ld * qd[j]
        x_lo = max(q[j] - q_lo[j], 0.0)
        w_lo = (1.0 - _sigmoid(qd[j] / lvg)) * lm / (x_lo / lml + lmeps)
        a_lo = lg / ((x_lo / lgl) ** 2 + lgeps) - ld * qd[j]
        a_rest = -pg * e[j] * scale - pd * qd[j]
        a_damp = -dg * speed * qd[j]
        A[j, j] += w_hi + w_lo + pm + dmetric
        b[j] += w_lo * a_lo - w_hi * a_hi + pm * a_rest + dmetric * a_damp
    # Cholesky solve A qdd = b
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s2 = A[i, j]
            for k in range(j):
                s2 -= L[i, k] * L[j, k]
            if i == j:
                if not s2 > 0.0:
                    return False
                L[i, i] = math.sqrt(s2)
            else:
                L[i, j] = s2 / L[j, j]
    zz = np.empty(n)
    for i in range(n):
        s2 = b[i]
        for k in range(i):
            s2 -= L[i, k] * zz[k]
        zz[i] = s2 / L[i, i]
    for i in range(n - 1, -1, -1):
        s2 = zz[i]
        for k in range(i + 1, n):
            s2 -= L[k, i] * qdd[k]
        qdd[i] = s2 / L[i, i]
    return True
