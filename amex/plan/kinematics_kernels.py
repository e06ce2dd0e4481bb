"""Compiled (Numba) batched kinematics: joint frames and capsule-sphere distances for all knots.

One compiled loop nest per quantity (~0.03 ms per evaluation at 400 knots, where numpy's ~80
small array operations cost ~0.4 ms), called by
:class:`~amex.plan.batch_kinematics.BatchKinematics` for every trajectory of two knots or more.
Bit for bit the numpy arithmetic, OpenBLAS's fused multiply-adds included (:func:`fma3`); why
and how: docs/planner.md, "Batched kinematics and compiled kernels".
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic


@intrinsic
def _fma(typingctx, a, b, c):  # type: ignore[no-untyped-def]
    """``a * b + c`` rounded once (LLVM's ``llvm.fma.f64``)."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        return builder.fma(*args)

    return signature, codegen


@numba.njit(cache=True, inline="always")
def fma3(a0: float, b0: float, a1: float, b1: float, a2: float, b2: float) -> float:
    """``a0 b0 + a1 b1 + a2 b2`` as OpenBLAS's matrix product computes it (from +0.0 on)."""
    return _fma(a2, b2, _fma(a1, b1, _fma(a0, b0, 0.0)))  # type: ignore[call-arg]


@numba.njit(cache=True)
def forward_frames(
    local: np.ndarray,
    parents: np.ndarray,
    sin: np.ndarray,
    cos: np.ndarray,
    axes: np.ndarray,
    pos: np.ndarray,
) -> None:
    """Fill ``axes`` (njoints, 3, 3, T) and ``pos`` (njoints, 3, T) for joint angles (nv, T).

    ``local`` (njoints, 4, 3), ``parents`` and the layout as in
    :meth:`~amex.plan.batch_kinematics.BatchKinematics.forward`; ``sin``, ``cos``: of the joint
    angles, shape (nv, T).
    """
    njoints, T = local.shape[0], sin.shape[1]
    for b in range(3):
        for a in range(3):
            for t in range(T):
                axes[0, b, a, t] = 1.0 if a == b else 0.0
    for a in range(3):
        for t in range(T):
            pos[0, a, t] = 0.0
    for j in range(1, njoints):
        p = parents[j]
        L = local[j]
        for a in range(3):
            for t in range(T):
                x0, x1, x2 = axes[p, 0, a, t], axes[p, 1, a, t], axes[p, 2, a, t]
                B0 = fma3(L[0, 0], x0, L[0, 1], x1, L[0, 2], x2)
                B1 = fma3(L[1, 0], x0, L[1, 1], x1, L[1, 2], x2)
                B2 = fma3(L[2, 0], x0, L[2, 1], x1, L[2, 2], x2)
                B3 = fma3(L[3, 0], x0, L[3, 1], x1, L[3, 2], x2)
                c, s = cos[j - 1, t], sin[j - 1, t]
                first = B0 * c
                second = B1 * s
                axes[j, 0, a, t] = first + second
                first = B1 * c
                second = B0 * s
                axes[j, 1, a, t] = first - second
                axes[j, 2, a, t] = B2
                pos[j, a, t] = pos[p, a, t] + B3


@numba.njit(cache=True)
def capsule_sphere_distances(
    axes: np.ndarray,
    pos: np.ndarray,
    cap_joint: np.ndarray,
    cap_ends: np.ndarray,
    cap_inv_len2: np.ndarray,
    cap_radius: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
    distance: np.ndarray,
    offset: np.ndarray,
) -> None:
    """Fill ``distance`` (C, k, T) and ``offset`` (C, k, 3, T) of every capsule to every sphere.

    As :meth:`~amex.plan.batch_kinematics.BatchKinematics.capsule_distances` for T >= 2:
    ``cap_ends[c]`` (2, 3) holds the segment's start and start-to-end vector in its joint's
    (turned) frame; ``centers`` (k, 3), ``radii`` (k,).
    """
    C, k, T = cap_joint.shape[0], radii.shape[0], axes.shape[3]
    start = np.empty(3)
    seg = np.empty(3)
    rel = np.empty(3)
    for c in range(C):
        j = cap_joint[c]
        E = cap_ends[c]
        neg_inv = -cap_inv_len2[c]
        for t in range(T):
            for a in range(3):
                x0, x1, x2 = axes[j, 0, a, t], axes[j, 1, a, t], axes[j, 2, a, t]
                start[a] = fma3(E[0, 0], x0, E[0, 1], x1, E[0, 2], x2) + pos[j, a, t]
                seg[a] = fma3(E[1, 0], x0, E[1, 1], x1, E[1, 2], x2)
            for o in range(k):
                for a in range(3):
                    rel[a] = start[a] - centers[o, a]
                p0, p1, p2 = rel[0] * seg[0], rel[1] * seg[1], rel[2] * seg[2]
                u = (p0 + p1) + p2
                u *= neg_inv
                if u == u:  # numpy's clip: NaN stays, max then min, -0.0 -> 0.0
                    u = u if u > 0.0 else 0.0
                    u = u if u < 1.0 else 1.0
                for a in range(3):
                    step = u * seg[a]
                    offset[c, o, a, t] = step + rel[a]
                q0 = offset[c, o, 0, t] * offset[c, o, 0, t]
                q1 = offset[c, o, 1, t] * offset[c, o, 1, t]
                q2 = offset[c, o, 2, t] * offset[c, o, 2, t]
                distance[c, o, t] = np.sqrt((q0 + q1) + q2) - (cap_radius[c] + radii[o])


@numba.njit(cache=True)
def final_terms_joint(
    J: np.ndarray,
    rotation: np.ndarray,
    p_last: np.ndarray,
    v: np.ndarray,
    Jwv: np.ndarray,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    w: np.ndarray,
    dt: float,
    Jz: np.ndarray,
    residual: np.ndarray,
    jac: np.ndarray,
) -> None:
    """The final terms of :func:`~amex.plan.optimizer.final_terms.final_terms`, joint velocity.

    Fills ``Jz`` (3, n), ``jac`` (9 + n, 2n) and ``residual`` (9 + n,) but its last three
    entries, ``w[3] * (Jz @ v)``, which numpy adds (its matrix-vector product sums in an order of
    its own). ``J`` (6, n): the TCP Jacobian; ``rotation``: the TCP orientation, whose third
    column is its z-axis; ``v``: the final joint
    velocity; ``Jwv``: ``J[3:] @ v`` from numpy.
    """
    n = v.shape[0]
    z = rotation[:, 2]
    # -skew(z), as numpy negates skew(z): its zeros become -0.0, -(-x) is x
    S = np.empty((3, 3))
    S[0, 0], S[0, 1], S[0, 2] = -0.0, z[2], -z[1]
    S[1, 0], S[1, 1], S[1, 2] = -z[2], -0.0, z[0]
    S[2, 0], S[2, 1], S[2, 2] = z[1], -z[0], -0.0
    W = np.empty((3, 3))  # skew(J_w v)
    W[0, 0], W[0, 1], W[0, 2] = 0.0, -Jwv[2], Jwv[1]
    W[1, 0], W[1, 1], W[1, 2] = Jwv[2], 0.0, -Jwv[0]
    W[2, 0], W[2, 1], W[2, 2] = -Jwv[1], Jwv[0], 0.0
    A = np.empty((3, n))  # J_w * v, then sum_{k>i} z_k v_k
    after = np.empty((3, n))
    for r in range(3):
        for i in range(n):
            Jz[r, i] = fma3(S[r, 0], J[3, i], S[r, 1], J[4, i], S[r, 2], J[5, i])
            A[r, i] = J[3 + r, i] * v[i]
        total = 0.0
        for k in range(n - 1, -1, -1):  # numpy's cumsum of the reversed row
            total = A[r, k] if k == n - 1 else total + A[r, k]
            after[r, k] = total - A[r, k]
    domega = np.empty((3, n))
    for i in range(n):
        first = J[4, i] * after[2, i]
        domega[0, i] = first - J[5, i] * after[1, i]
        first = J[5, i] * after[0, i]
        domega[1, i] = first - J[3, i] * after[2, i]
        first = J[3, i] * after[1, i]
        domega[2, i] = first - J[4, i] * after[0, i]
    for r in range(9 + n):
        for c in range(2 * n):
            jac[r, c] = 0.0
    m = n
    for r in range(3):
        residual[r] = w[0] * (p_last[r] - goal_pos[r])
        residual[3 + m + r] = w[2] * (z[r] - goal_axis[r])
        for i in range(n):
            jac[r, n + i] = w[0] * J[r, i]
            jac[3 + m + r, n + i] = w[2] * Jz[r, i]
            dz = fma3(S[r, 0], domega[0, i], S[r, 1], domega[1, i], S[r, 2], domega[2, i])
            dz2 = fma3(W[r, 0], Jz[0, i], W[r, 1], Jz[1, i], W[r, 2], Jz[2, i])
            dzdot = dz + dz2
            jac[6 + m + r, i] = ((-w[3]) * Jz[r, i]) / dt
            jac[6 + m + r, n + i] = w[3] * (Jz[r, i] / dt + dzdot)
    for r in range(m):
        residual[3 + r] = w[1] * v[r]
        for c in range(n):
            unit = (1.0 if r == c else 0.0) / dt  # np.eye(n) / dt
            jac[3 + r, c] = w[1] * -unit
            jac[3 + r, n + c] = w[1] * unit


@numba.njit(cache=True)
def pair_gradients(
    axis: np.ndarray,
    position: np.ndarray,
    offset: np.ndarray,
    centers: np.ndarray,
    support: np.ndarray,
    cap: np.ndarray,
    obs: np.ndarray,
    knot: np.ndarray,
    out: np.ndarray,
) -> None:
    """Fill ``out`` (P, nv) with the distance gradients of the pairs ``(cap, obs, knot)``.

    As :meth:`~amex.plan.batch_kinematics.BatchKinematics.distance_gradients`: ``axis``
    (njoints, 3, T) and ``position`` (njoints, 3, T) from the frames, ``offset`` (C, k, 3, T)
    from the distances, ``support`` (C, nv) the joints that move each capsule.
    """
    nv = out.shape[1]
    line = np.empty(6)
    wn = np.empty(6)
    for p in range(cap.shape[0]):
        c, o, t = cap[p], obs[p], knot[p]
        o0, o1, o2 = offset[c, o, 0, t], offset[c, o, 1, t], offset[c, o, 2, t]
        q0, q1, q2 = o0 * o0, o1 * o1, o2 * o2
        norm = np.sqrt((q0 + q2) + q1)  # numpy's einsum over three contiguous entries
        norm = norm if norm > 1e-12 or norm != norm else 1e-12  # np.maximum(norm, 1e-12)
        n0, n1, n2 = o0 / norm, o1 / norm, o2 / norm
        x0, x1, x2 = centers[o, 0] + o0, centers[o, 1] + o1, centers[o, 2] + o2
        first = x1 * n2
        wn[0] = first - x2 * n1
        first = x2 * n0
        wn[1] = first - x0 * n2
        first = x0 * n1
        wn[2] = first - x1 * n0
        wn[3], wn[4], wn[5] = n0, n1, n2
        for i in range(nv):
            z0, z1, z2 = axis[i + 1, 0, t], axis[i + 1, 1, t], axis[i + 1, 2, t]
            p0, p1, p2 = position[i + 1, 0, t], position[i + 1, 1, t], position[i + 1, 2, t]
            line[0], line[1], line[2] = z0, z1, z2
            first = p1 * z2
            line[3] = first - p2 * z1
            first = p2 * z0
            line[4] = first - p0 * z2
            first = p0 * z1
            line[5] = first - p1 * z0
            total = 0.0
            for a in range(6):
                total += wn[a] * line[a]
            out[p, i] = total * (1.0 if support[c, i] else 0.0)


@numba.njit(cache=True)
def near_pairs(
    distance: np.ndarray, margin: float, guard: float, scale: float, r_col: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs with ``1 - d / margin > -guard``, sorted by knot, and their residuals.

    Returns ``(cap, obs, knot, r)`` with ``r = scale * max(1 - d / margin, 0)``, and writes ``r``
    into ``r_col`` (C, k, T) at the pairs: what ``np.nonzero`` of the transposed test and the
    numpy expressions of :func:`amex.plan.optimizer.residuals.residuals` give.
    """
    C, k, T = distance.shape
    count = 0
    for t in range(T):
        for c in range(C):
            for o in range(k):
                if 1.0 - distance[c, o, t] / margin > -guard:
                    count += 1
    cap = np.empty(count, dtype=np.int64)
    obs = np.empty(count, dtype=np.int64)
    knot = np.empty(count, dtype=np.int64)
    r = np.empty(count)
    p = 0
    for t in range(T):
        for c in range(C):
            for o in range(k):
                depth = 1.0 - distance[c, o, t] / margin
                if depth > -guard:
                    cap[p], obs[p], knot[p] = c, o, t
                    value = depth if depth > 0.0 or depth != depth else 0.0  # np.maximum
                    r[p] = scale * value
                    r_col[c, o, t] = r[p]
                    p += 1
    return cap, obs, knot, r
