"""Compiled (Numba) blends of :mod:`amex.plan.knots`: CR's warm starts and joint targets.

Apart from :mod:`amex.plan.knots`, so that a run that builds no CR never imports Numba
(:mod:`amex.core.compiled`). Compiled without ``fastmath``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def blend_rows(knots: np.ndarray, offset: float, stride: float, out: np.ndarray) -> None:
    """Row ``k`` of ``out`` at index ``offset + k stride``, as ``resample_knots_numpy`` blends."""
    last = knots.shape[0] - 1
    for k in range(out.shape[0]):
        u = offset + stride * float(k)
        if u == u:  # numpy's clip: NaN stays, max then min, -0.0 -> 0.0
            u = u if u > 0.0 else 0.0
            u = u if u < float(last) else float(last)
        nearest = np.rint(u)
        if abs(u - nearest) <= 1e-9:
            u = nearest
        if last == 0:
            out[k] = knots[0]
            continue
        i = min(int(np.floor(u)), max(last - 1, 0))
        a = u - float(i)
        for j in range(knots.shape[1]):
            out[k, j] = (1.0 - a) * knots[i, j] + a * knots[i + 1, j]


@numba.njit(cache=True)
def midpoint_target(
    knots: np.ndarray, stride: float, dt: float, q_mid: np.ndarray, qd: np.ndarray
) -> None:
    """CR's joint target from its knots, one compiled call: ``q_mid`` and ``qd``, shapes (n,).

    Rows at indices ``0, stride, 2 stride`` blended as :func:`~amex.plan.knots.resample_knots`
    blends them (``stride`` not within 1e-9 of an integer, ``len(knots) >= 2``): ``q_mid`` the
    middle row, ``qd = (q[2] - q[0]) / dt``, the numpy expression of ``CR.target``, bit for bit.
    """
    rows = np.empty((3, knots.shape[1]))
    blend_rows(knots, 0.0, stride, rows)
    for j in range(knots.shape[1]):
        q_mid[j] = rows[1, j]
        qd[j] = (rows[2, j] - rows[0, j]) / dt
