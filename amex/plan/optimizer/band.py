"""Symmetric band matrices in LAPACK's lower storage: the trajectory's Gauss-Newton matrix.

With the knots stacked knot-major the matrix ``2 J^T J`` has bandwidth ``2n`` (docs/planner.md):
entry ``H[i, j]``, ``0 <= i - j <= 2n``, is stored at ``band[i - j, j]``, shape (2n + 1, nT), in
Fortran order, and solved by one banded Cholesky (``dpbsv``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.linalg import LinAlgError
from scipy.linalg.lapack import dpbsv as _dpbsv

__all__ = ["acceleration_band", "add_block", "band_memory", "lower_triangle", "solve_band"]


@lru_cache(maxsize=8)
def acceleration_band(
    n: int, T: int, dt: float, weight: float, metric: tuple[float, ...] = ()
) -> np.ndarray:
    """``2 J_acc^T J_acc`` in lower band storage (2n subdiagonals), shape (2n + 1, nT); read-only.

    J_acc is ``sqrt(weight dt) / dt^2`` times the second-difference operator D on the free knots,
    so the matrix is ``kron(D^T D, I_n)`` scaled (``kron(D^T D, H)`` with a joint ``metric``
    diag(H)); D^T D is pentadiagonal: diagonal 6 (5 and 1 at the last two knots), first
    off-diagonal -4 (-2 at the last), second off-diagonal 1.
    """
    scale = 2.0 * weight / dt**3
    band = np.zeros((2 * n + 1, n * T))
    band[0] = 6.0 * scale
    band[0, n * max(T - 2, 0) : n * max(T - 1, 0)] = 5.0 * scale
    band[0, n * (T - 1) :] = scale
    band[n, : n * max(T - 1, 0)] = -4.0 * scale
    band[n, n * max(T - 2, 0) : n * max(T - 1, 0)] = -2.0 * scale
    band[2 * n, : n * max(T - 2, 0)] = scale
    if metric:  # every band entry couples a joint with itself: scale its column by H_jj
        band *= np.tile(np.asarray(metric, dtype=float), T)
    band = np.asfortranarray(band)  # LAPACK's layout (NormalEquations)
    band.flags.writeable = False
    return band


@lru_cache(maxsize=4)
def lower_triangle(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the lower triangle of an (m, m) matrix, ``i >= j``."""
    i, j = np.tril_indices(m)
    return i, j


def add_block(band: np.ndarray, block: np.ndarray, first: int) -> None:
    """Add a symmetric ``block`` starting at row/column ``first`` to a lower band matrix."""
    i, j = lower_triangle(block.shape[0])
    band_memory(band)[(first + j) * band.shape[0] + (i - j)] += block[i, j]


def band_memory(band: np.ndarray) -> np.ndarray:
    """A Fortran-ordered band as a flat view: entry ``[d, col]`` is at ``col * (2n + 1) + d``."""
    return band.T.reshape(-1)


def solve_band(band: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``x`` with ``A x = rhs`` for ``A`` in lower band storage; ``band`` and ``rhs`` are consumed.

    LAPACK's ``dpbsv`` called directly: what ``scipy.linalg.solveh_banded(band, rhs, lower=True,
    overwrite_ab=True, overwrite_b=True, check_finite=False)`` calls, without its ~20 us of
    checks per call (the same result to the bit).

    Raises:
        LinAlgError: the matrix is not positive definite.
    """
    _, x, info = _dpbsv(band, rhs, lower=1, overwrite_ab=1, overwrite_b=1)
    if info > 0:
        raise LinAlgError(f"{info}th leading minor not positive definite")
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal pbsv")
    return x
