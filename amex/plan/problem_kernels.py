"""Compiled (Numba) check of :class:`amex.plan.problem.TrajectoryProblem`'s arrays.

Apart from :mod:`amex.plan.problem`, whose cost terms every run's checks build, so that a run
that solves no plan never imports Numba (:mod:`amex.core.compiled`).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _finite(a: np.ndarray) -> bool:
    for value in a.ravel():  # noqa: SIM110 (a loop Numba compiles)
        if not np.isfinite(value):
            return False
    return True


@numba.njit(cache=True)
def all_finite(
    q: np.ndarray, v: np.ndarray, g: np.ndarray, a: np.ndarray, o: np.ndarray, r: np.ndarray
) -> bool:
    """Whether every entry of the six arrays is finite."""
    return _finite(q) and _finite(v) and _finite(g) and _finite(a) and _finite(o) and _finite(r)
