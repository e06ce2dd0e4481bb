"""Compiled (Numba) assembly of one Gauss-Newton iteration: residuals, gradient, damped band.

The glue around the kinematics kernels (:mod:`amex.plan.kinematics_kernels`) and the banded
Cholesky, which numpy spent ~60 small array operations per iteration on (docs/planner.md,
"Compiled assembly"). Bit for bit the numpy of :mod:`~amex.plan.optimizer.residuals`,
:mod:`~amex.plan.optimizer.linearize` and :func:`~amex.plan.optimizer.numpy_assembly.damped_step`
(the oracles, ``tests/plan/test_assembly.py``): elementwise arithmetic in numpy's order, and
numpy's ``add.reduceat`` (the per-knot sums of the collision pairs) as numpy adds: the first
term plus the pairwise sum of the rest (:func:`pairwise_sum`). Dot products and small matrix
products stay with numpy (OpenBLAS sums in orders of its own).
"""

from __future__ import annotations

import numba
import numpy as np

#: numpy's pairwise summation block (``PW_BLOCKSIZE``).
_BLOCK = 128


@numba.njit(cache=True)
def pairwise_sum(values: np.ndarray, start: int, count: int) -> float:
    """The pairwise sum of ``values[start : start + count]``, numpy's ``@TYPE@_pairwise_sum``.

    Below 8 terms a loop from -0.0; up to 128, eight accumulators combined as
    ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))`` then the rest in order; above, the
    two halves (the first a multiple of 8 long) summed recursively.
    """
    if count < 8:
        total = -0.0
        for i in range(count):
            total += values[start + i]
        return total
    if count <= _BLOCK:
        r0, r1, r2, r3 = values[start], values[start + 1], values[start + 2], values[start + 3]
        r4, r5, r6, r7 = values[start + 4], values[start + 5], values[start + 6], values[start + 7]
        i = 8
        stop = count - count % 8
        while i < stop:
            b = start + i
            r0 += values[b]
            r1 += values[b + 1]
            r2 += values[b + 2]
            r3 += values[b + 3]
            r4 += values[b + 4]
            r5 += values[b + 5]
            r6 += values[b + 6]
            r7 += values[b + 7]
            i += 8
        total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < count:
            total += values[start + i]
            i += 1
        return total
    half = count // 2
    half -= half % 8
    return pairwise_sum(values, start, half) + pairwise_sum(values, start + half, count - half)


@numba.njit(cache=True)
def segment_sum(values: np.ndarray, start: int, stop: int) -> float:
    """``np.add.reduceat``'s sum of ``values[start:stop]``: the first plus the pairwise rest."""
    if stop - start == 1:
        return values[start]
    return values[start] + pairwise_sum(values, start + 1, stop - start - 1)


@numba.njit(cache=True)
def acceleration_residuals(
    x: np.ndarray,
    q_start: np.ndarray,
    v_start: np.ndarray,
    dt: float,
    scale: np.ndarray,
    r_acc: np.ndarray,
) -> None:
    """Fill ``r_acc`` (T, n): ``scale (q_{t+1} - 2 q_t + q_{t-1})`` with ``q_-1 = q_0 - dt v``.

    As :func:`~amex.plan.optimizer.residuals.residuals` computes it: first differences, their
    differences, ``- dt v_start`` at the first knot, times ``scale`` (n,) per joint.
    """
    T, n = x.shape
    for j in range(n):
        before = x[0, j] - q_start[j]
        r_acc[0, j] = (before - dt * v_start[j]) * scale[j]
        for t in range(1, T):
            diff = x[t, j] - x[t - 1, j]
            r_acc[t, j] = (diff - before) * scale[j]
            before = diff


@numba.njit(cache=True)
def gradient_rhs(
    r_acc: np.ndarray,
    scale2: np.ndarray,
    final_Jtr: np.ndarray,
    knot: np.ndarray,
    r_near: np.ndarray,
    J_col: np.ndarray,
    rhs: np.ndarray,
) -> None:
    """Fill ``rhs`` (nT,) with ``-2 J^T r``, the right-hand side of the damped step.

    The gradient of :func:`~amex.plan.optimizer.linearize.linearize`: ``D^T r_acc`` times
    ``scale2`` (n,) (``2 s_acc``), plus ``2 final_Jtr`` (m,) (``J_fin^T r_fin`` from numpy) on
    the last m entries, plus per knot the sum of ``2 r_p J_col[p]`` over its pairs p (``knot``
    (P,) sorted, ``J_col`` (P, n) the collision residuals' Jacobian rows).
    """
    T, n = r_acc.shape
    m = final_Jtr.shape[0]
    size = T * n
    for t in range(T):
        for j in range(n):
            g = r_acc[t, j]
            if t + 1 < T:
                g = g - 2.0 * r_acc[t + 1, j]
            if t + 2 < T:
                g = g + r_acc[t + 2, j]
            rhs[t * n + j] = g * scale2[j]
    for i in range(m):
        rhs[size - m + i] += 2.0 * final_Jtr[i]
    P = r_near.shape[0]
    terms = np.empty(P)
    start = 0
    while start < P:
        stop = _group_end(knot, start)
        for j in range(n):
            for p in range(start, stop):
                terms[p] = (2.0 * r_near[p]) * J_col[p, j]
            rhs[knot[start] * n + j] += segment_sum(terms, start, stop)
        start = stop
    for i in range(size):
        rhs[i] = -rhs[i]


@numba.njit(cache=True)
def _group_end(knot: np.ndarray, start: int) -> int:
    """The end of the run of pairs at knot ``knot[start]`` (``knot`` sorted)."""
    stop = start + 1
    while stop < knot.shape[0] and knot[stop] == knot[start]:
        stop += 1
    return stop


@numba.njit(cache=True)
def _add_pair_curvature(
    band: np.ndarray, n: int, knot: np.ndarray, J_col: np.ndarray, mask: np.ndarray
) -> None:
    """``band += sum_p mask_p 2 J_p^T J_p`` per knot, summed as ``add.reduceat`` sums."""
    P = J_col.shape[0]
    terms = np.empty(P)
    start = 0
    while start < P:
        stop = _group_end(knot, start)
        col0 = knot[start] * n
        for i in range(n):
            for j in range(i + 1):
                for p in range(start, stop):
                    terms[p] = ((2.0 * J_col[p, i]) * J_col[p, j]) * mask[p]
                band[i - j, col0 + j] += segment_sum(terms, start, stop)
        start = stop


@numba.njit(cache=True)
def damped_system(
    band: np.ndarray,
    rhs: np.ndarray,
    scale: float,
    metric: np.ndarray,
    final_JtJ: np.ndarray,
    final_Jtr: np.ndarray,
    final_first: int,
    r_acc: np.ndarray,
    s_acc2: np.ndarray,
    cap: np.ndarray,
    obs: np.ndarray,
    knot: np.ndarray,
    J_col: np.ndarray,
    r_near: np.ndarray,
    woken: np.ndarray,
    lam: float,
) -> bool:
    """The damped step's system: the band and the right-hand side, in one call.

    :func:`damped_band` into ``band``, :func:`gradient_rhs` into ``rhs``; whether ``G`` was
    added.
    """
    gradient_rhs(r_acc, s_acc2, final_Jtr, knot, r_near, J_col, rhs)
    return damped_band(
        band, scale, metric, final_JtJ, final_first, cap, obs, knot, J_col, r_near, woken, lam
    )


@numba.njit(cache=True)
def damped_band(
    band: np.ndarray,
    scale: float,
    metric: np.ndarray,
    final_JtJ: np.ndarray,
    final_first: int,
    cap: np.ndarray,
    obs: np.ndarray,
    knot: np.ndarray,
    J_col: np.ndarray,
    r_near: np.ndarray,
    woken: np.ndarray,
    lam: float,
) -> bool:
    """Fill ``band`` (2n + 1, nT) with ``H + G + lambda I`` in lower band storage.

    ``H``: the acceleration band (:func:`~amex.plan.optimizer.band.acceleration_band`, factor
    ``scale`` ``= 2 w / dt^3``, joint ``metric`` (n,), empty: none), plus ``2 final_JtJ`` (m, m)
    (``J_fin^T J_fin`` from numpy) from row/column ``final_first``, plus the active collision
    pairs' ``2 J^T J`` (``r_near > 0``); ``G``: the pairs ``(cap, obs, knot)`` that are
    ``woken`` and inactive, added only if there is one (the numpy damped step,
    :func:`~amex.plan.optimizer.numpy_assembly.damped_step`). Every entry is summed in the numpy
    version's order. Returns whether ``G`` was added.
    """
    width, size = band.shape
    n = (width - 1) // 2
    T = size // n
    P = r_near.shape[0]
    touched = np.zeros(T, dtype=np.bool_)  # knots whose diagonal gets more than H: lambda last
    for p in range(P):
        touched[knot[p]] = True
    for col in range(final_first, size):
        touched[col // n] = True
    s6, s5, s4, s2 = 6.0 * scale, 5.0 * scale, -4.0 * scale, -2.0 * scale
    weighted = metric.shape[0] > 0
    band.T.reshape(-1)[:] = 0.0  # one pass over the memory (0 h = 0 for the metric's h > 0)
    for t in range(T):
        diagonal = scale if t == T - 1 else (s5 if t == T - 2 else s6)
        first_off = 0.0 if t >= T - 1 else (s2 if t == T - 2 else s4)
        second_off = scale if t < T - 2 else 0.0
        shift = 0.0 if touched[t] else lam
        for j in range(n):
            col = t * n + j
            h = metric[j] if weighted else 1.0  # (c scale) h as numpy scales by the metric; x 1 = x
            band[0, col] = diagonal * h + shift
            band[n, col] = first_off * h
            band[2 * n, col] = second_off * h
    m = final_JtJ.shape[0]
    for i in range(m):
        for j in range(i + 1):
            band[i - j, final_first + j] += 2.0 * final_JtJ[i, j]
    mask = np.empty(P)
    guarded = False
    for p in range(P):
        mask[p] = 1.0 if r_near[p] > 0.0 else 0.0
    _add_pair_curvature(band, n, knot, J_col, mask)
    for p in range(P):
        inactive = woken[cap[p], obs[p], knot[p]] and r_near[p] == 0.0
        mask[p] = 1.0 if inactive else 0.0
        guarded = guarded or inactive
    if guarded:
        _add_pair_curvature(band, n, knot, J_col, mask)
    for t in range(T):
        if touched[t]:
            for j in range(n):
                band[0, t * n + j] += lam
    return guarded


@numba.njit(cache=True)
def wake_pairs(
    cap: np.ndarray,
    obs: np.ndarray,
    knot: np.ndarray,
    r_near: np.ndarray,
    trial_distance: np.ndarray,
    margin: float,
    scale: float,
    woken: np.ndarray,
) -> bool:
    """Wake the pairs inactive at the current point that the trial made active; whether any.

    The trial's residual of a pair is :func:`~amex.plan.kinematics_kernels.near_pairs`'
    ``scale max(1 - d / margin, 0)`` of its distance ``trial_distance`` (C, k, T) (zero beyond
    the guard: not active either), so the numpy version's test of the trial's residuals
    (:func:`~amex.plan.optimizer.numpy_assembly.wake_pushed_in`) is made on the distances.
    """
    P = cap.shape[0]
    newly = np.zeros(P, dtype=np.bool_)
    for p in range(P):
        c, o, t = cap[p], obs[p], knot[p]
        depth = 1.0 - trial_distance[c, o, t] / margin
        value = depth if depth > 0.0 or depth != depth else 0.0  # np.maximum
        newly[p] = scale * value > 0.0 and r_near[p] == 0.0 and not woken[c, o, t]
    found = False
    for p in range(P):
        if newly[p]:
            woken[cap[p], obs[p], knot[p]] = True
            found = True
    return found


@numba.njit(cache=True)
def equal(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.array_equal`` of two arrays of one shape (``==`` entry by entry: -0.0 equals 0.0)."""
    flat_a, flat_b = a.reshape(-1), b.reshape(-1)
    for i in range(flat_a.shape[0]):  # noqa: SIM110 (a loop Numba compiles)
        if flat_a[i] != flat_b[i]:
            return False
    return True


@numba.njit(cache=True)
def take_step(
    x: np.ndarray,
    step: np.ndarray,
    q_start: np.ndarray,
    v_start: np.ndarray,
    dt: float,
    scale: np.ndarray,
    tolerance: float,
    out: np.ndarray,
    r_acc: np.ndarray,
    v_last: np.ndarray,
) -> bool:
    """``out = x + step`` and its acceleration residuals; whether every ``|step|`` is small.

    ``step`` (nT,); ``r_acc`` as :func:`acceleration_residuals` fills it; ``v_last`` (n,) the
    final joint velocity ``(q_T - q_{T-1}) / dt`` of ``out`` (``q_0`` the start for T = 1), as
    :func:`~amex.plan.optimizer.final_terms.final_terms` computes it. The answer is the solver's
    ``max |step| < tolerance`` (False with a NaN).
    """
    T, n = x.shape
    flat_x, flat_out = x.reshape(-1), out.reshape(-1)
    large = 0
    for i in range(T * n):
        s = step[i]
        flat_out[i] = flat_x[i] + s
        large += 0 if abs(s) < tolerance else 1
    acceleration_residuals(out, q_start, v_start, dt, scale, r_acc)
    last_velocity(out, q_start, dt, v_last)
    return large == 0


@numba.njit(cache=True)
def last_velocity(x: np.ndarray, q_start: np.ndarray, dt: float, v_last: np.ndarray) -> None:
    """``v_last = (q_T - q_{T-1}) / dt`` of the free knots ``x`` (``q_0`` the start for T = 1)."""
    T, n = x.shape
    for j in range(n):
        before = x[T - 2, j] if T > 1 else q_start[j]
        v_last[j] = (x[T - 1, j] - before) / dt


@numba.njit(cache=True)
def start_residuals(
    x: np.ndarray,
    q_start: np.ndarray,
    v_start: np.ndarray,
    dt: float,
    scale: np.ndarray,
    r_acc: np.ndarray,
    v_last: np.ndarray,
) -> None:
    """:func:`acceleration_residuals` and :func:`last_velocity` of ``x``, in one call."""
    acceleration_residuals(x, q_start, v_start, dt, scale, r_acc)
    last_velocity(x, q_start, dt, v_last)
