"""Compiled (Numba) steps of the momentum observer (:mod:`amex.control.disturbance`).

Apart from :mod:`amex.control.disturbance`, whose configuration every run reads, so that a run
without the observer never imports Numba (:mod:`amex.core.compiled`). Compiled without
``fastmath``.
"""

from __future__ import annotations

import numba


@numba.njit(cache=True)
def observer_update(M, C, g, v, started, a, inv_dt, bound, r, p_prev, flow_prev, beta) -> None:
    """One step of the discrete observer, in place: ``r``, ``p_prev`` and ``beta``.

    ``p = M v`` (M's upper triangle), ``d = (p - p_prev) / dt - flow_prev``,
    ``r = clip(a r + (1 - a) d, -bound, bound)`` (skipped on the first step, which only records
    ``p``), and ``beta = C^T v - g`` for the coming step.
    """
    n = v.shape[0]
    for i in range(n):
        p = 0.0
        for j in range(n):
            p += (M[i, j] if i <= j else M[j, i]) * v[j]
        if started:
            ri = a * r[i] + (1.0 - a) * ((p - p_prev[i]) * inv_dt - flow_prev[i])
            if ri > bound[i]:
                ri = bound[i]
            elif ri < -bound[i]:
                ri = -bound[i]
            r[i] = ri
        p_prev[i] = p
        ctv = 0.0
        for j in range(n):
            ctv += C[j, i] * v[j]
        beta[i] = ctv - g[i]


@numba.njit(cache=True)
def compensate_and_clip(tau, r, lo, hi) -> None:
    """``tau = clip(tau - r, lo, hi)`` in place (NaN stays NaN)."""
    for i in range(tau.shape[0]):
        x = tau[i] - r[i]
        if x < lo[i]:
            x = lo[i]
        elif x > hi[i]:
            x = hi[i]
        tau[i] = x
