"""CR's Gauss-Newton iteration in three compiled calls between Pinocchio's (issue #29).

Each function here is a sequence the compiled iteration (:class:`~.assembly.CompiledSolve`)
made as several Python-level calls, now one call, with numpy's small products made by the
routines numpy makes them with (:mod:`.blas`), so the numbers are the same bits:

* :func:`final_cost`: the final residuals and their Jacobian at the last knot from Pinocchio's
  frame Jacobian and placement (joint-velocity form, :func:`~amex.plan.kinematics_kernels.
  final_terms_joint`, eqs. of the final position, axis and velocity terms), the axis rate
  ``w[3] J_z v``, and the cost without collision term ``|r_acc|^2 + |r_fin|^2``.
* :func:`final_products`: ``J_fin^T J_fin`` and ``J_fin^T r_fin`` of the normal equations.
* :func:`damped_solve`: the damped band and right-hand side (:func:`.assembly_kernels.
  damped_system`) and LAPACK's banded Cholesky ``dpbsv`` on them.

Every function requires :data:`.blas.BOUND` and ``n >= 2`` joints (numpy calls other routines
for a single column); the caller keeps the numpy path otherwise.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from amex.plan.kinematics_kernels import final_terms_joint
from amex.plan.optimizer.assembly_kernels import damped_system
from amex.plan.optimizer.blas import ddot, dot_rows, dpbsv, gram_upper, transposed_dot

__all__ = ["damped_solve", "final_cost", "final_products"]


@numba.njit(cache=True)
def final_cost(
    J: np.ndarray,
    rotation: np.ndarray,
    p_last: np.ndarray,
    v_last: np.ndarray,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    w: np.ndarray,
    dt: float,
    rows: np.ndarray,
    Jz: np.ndarray,
    r_fin: np.ndarray,
    J_fin: np.ndarray,
    r_acc: np.ndarray,
) -> float:
    """Fill ``r_fin`` (9 + n,) and ``J_fin`` (9 + n, 2n); return ``|r_acc|^2 + |r_fin|^2``.

    ``J`` (6, n) and ``rotation``, ``p_last``: Pinocchio's TCP Jacobian (world-aligned) and
    placement at the last knot; ``v_last``: the final joint velocity; ``w``: the final weights'
    square roots; ``rows`` (3, n) and ``Jz`` (3, n): scratch. numpy's order: ``J[3:] @ v``
    (copied to C order first, as numpy copies a matrix that is not one segment), the terms, then
    ``w[3] (J_z @ v)`` into the last three residuals, then the two dot products summed.
    """
    n = v_last.shape[0]
    for r in range(3):
        for i in range(n):
            rows[r, i] = J[3 + r, i]
    Jwv = np.empty(3)
    dot_rows(rows, v_last, Jwv)
    final_terms_joint(
        J, rotation, p_last, v_last, Jwv, goal_pos, goal_axis, w, dt, Jz, r_fin, J_fin
    )
    rate = np.empty(3)
    dot_rows(Jz, v_last, rate)
    w3 = w[3]
    for r in range(3):
        r_fin[6 + n + r] = rate[r] * w3
    flat = r_acc.reshape(-1)
    return ddot(flat, flat) + ddot(r_fin, r_fin)


@numba.njit(cache=True)
def final_products(J_fin: np.ndarray, r_fin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(J_fin.T @ J_fin, J_fin.T.dot(r_fin))`` for a C-contiguous ``J_fin`` (m, k), k >= 2."""
    k = J_fin.shape[1]
    JtJ = np.empty((k, k))
    gram_upper(J_fin, JtJ)
    Jtr = np.empty(k)
    transposed_dot(J_fin, r_fin, Jtr)
    return JtJ, Jtr


@numba.njit(cache=True)
def damped_solve(band: np.ndarray, rhs: np.ndarray, *terms: Any) -> int:
    """:func:`~.assembly_kernels.damped_system` into ``band`` and ``rhs``, then ``dpbsv``.

    ``terms``: the system's terms after its two buffers, in ``damped_system``'s order
    (:meth:`~.assembly.CompiledSolve.system_terms`). ``rhs`` holds the step ``dx`` afterwards;
    returns LAPACK's ``info`` (0: solved; > 0: the leading minor of that order is not positive
    definite).
    """
    damped_system(band, rhs, *terms)
    return dpbsv(band, rhs)
