"""Compiled (Numba) collision tasks: value and Jacobian of Eq. 5's third row from coal's results.

Both kernels read one step's distances as :class:`~amex.control.collision.CollisionModel` leaves
them (its ``table``: distance, normal, witness points per pair, a view of coal's own results), and
Pinocchio's world-frame joint Jacobians ``data.J`` (``computeJointJacobians``; column i the
spatial velocity (v_i, w_i) of joint i at the world origin), so the task costs no Python call per
pair. Each writes ``(phi, d phi / d q)`` into one buffer, the controller's collision input
(:func:`amex.control.kernels.normal_equations`). The Jacobian of a world point p on the arm is
``v_i + w_i x p`` for the joints i that move it (``support``), the same point Jacobian as
:func:`amex.control.tasks.point_jacobian`; the numpy oracles are
:meth:`~amex.control.tasks.CollisionMap.evaluate` and :meth:`~amex.control.tasks.ProxyMap.evaluate`.
Their BLAS products sum in another order, so the two agree to rounding (~1e-16 relative), not
bit for bit. Compiled without ``fastmath``.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _normal(table: np.ndarray, k: int, centers: np.ndarray, obstacle: int) -> tuple:
    """Unit normal from the obstacle to the arm at pair k (as ``CollisionModel.proximities``)."""
    ax, ay, az = table[k, 4], table[k, 5], table[k, 6]
    dx, dy, dz = ax - table[k, 7], ay - table[k, 8], az - table[k, 9]
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    if norm > 1e-9 and table[k, 0] > 0:
        return dx / norm, dy / norm, dz / norm
    # touching or penetrating: along the direction from the obstacle's centre to the point
    ux, uy, uz = ax - centers[obstacle, 0], ay - centers[obstacle, 1], az - centers[obstacle, 2]
    s = max(math.sqrt(ux * ux + uy * uy + uz * uz), 1e-12)
    return ux / s, uy / s, uz / s


@numba.njit(cache=True)
def _subtract_point_gradient(
    out: np.ndarray,
    scale: float,
    ux: float,
    uy: float,
    uz: float,
    px: float,
    py: float,
    pz: float,
    J_world: np.ndarray,
    support: np.ndarray,
    k: int,
) -> None:
    """``out[1:] -= scale * u^T J(p)``, J(p) the linear Jacobian of the arm point p of pair k."""
    for i in range(out.shape[0] - 1):
        if support[k, i] != 0.0:
            wx, wy, wz = J_world[3, i], J_world[4, i], J_world[5, i]
            jx = J_world[0, i] + (wy * pz - wz * py)
            jy = J_world[1, i] + (wz * px - wx * pz)
            jz = J_world[2, i] + (wx * py - wy * px)
            out[1 + i] -= scale * (ux * jx + uy * jy + uz * jz)


@numba.njit(cache=True)
def hinge_terms(
    out: np.ndarray,
    table: np.ndarray,
    J_world: np.ndarray,
    support: np.ndarray,
    pair_obstacle: np.ndarray,
    centers: np.ndarray,
    margin: float,
) -> float:
    """The hinge ``phi = sum_k (margin - d_k)`` over the pairs closer than ``margin``; ``out = J``.

    Args:
        out: ``(phi, d phi / d q)``, shape (1 + n,), overwritten.
        table: the pairs' distances and witness points (``CollisionModel.table``).
        J_world: world-frame joint Jacobians, shape (6, n) (Pinocchio's ``data.J``).
        support: 1 where joint column i moves the arm shape of pair k, shape (n_pairs, n).
        pair_obstacle: the obstacle of each pair, shape (n_pairs,).
        centers: the obstacles' centres, shape (n_obstacles, 3) [m].
        margin: the margin [m].

    Returns:
        phi [m] (0 when no pair is inside the margin).
    """
    for i in range(out.shape[0]):
        out[i] = 0.0
    phi = 0.0
    for k in range(table.shape[0]):
        d = table[k, 0]
        if d >= margin:
            continue
        nx, ny, nz = _normal(table, k, centers, pair_obstacle[k])
        ax, ay, az = table[k, 4], table[k, 5], table[k, 6]
        _subtract_point_gradient(out, 1.0, nx, ny, nz, ax, ay, az, J_world, support, k)
        phi += margin - d
    out[0] = phi
    return phi


@numba.njit(cache=True)
def proxy_terms(
    out: np.ndarray,
    table: np.ndarray,
    placements: np.ndarray,
    J_world: np.ndarray,
    support: np.ndarray,
    pair_obstacle: np.ndarray,
    pair_arm: np.ndarray,
    centers: np.ndarray,
    reach: np.ndarray,
    margin: float,
) -> float:
    """The authors' proxy cost ``phi = sum_p (1 - d_p / m)(1 - c_p / a_p)``; ``out = J`` (ProxyMap).

    Args:
        out: ``(phi, d phi / d q)``, shape (1 + n,), overwritten.
        table: as :func:`hinge_terms`.
        J_world: as :func:`hinge_terms`.
        support: as :func:`hinge_terms`.
        pair_obstacle: as :func:`hinge_terms`.
        centers: as :func:`hinge_terms`.
        placements: the geometry placements (``CollisionModel.placements``); the arm shape of a
            pair has the geometry index of its arm shape, whose translation is the shape's centre.
        pair_arm: the arm shape of each pair, shape (n_pairs,).
        reach: a_p of each arm shape, shape (n_arm,) [m].
        margin: m [m].

    Returns:
        phi (dimensionless; 0 when no pair is inside the margin).
    """
    for i in range(out.shape[0]):
        out[i] = 0.0
    phi = 0.0
    m = margin
    for k in range(table.shape[0]):
        d = table[k, 0]
        if d >= m:
            continue
        obstacle, arm = pair_obstacle[k], pair_arm[k]
        cx, cy, cz = placements[arm, 9], placements[arm, 10], placements[arm, 11]
        ux, uy, uz = cx - centers[obstacle, 0], cy - centers[obstacle, 1], cz - centers[obstacle, 2]
        c = math.sqrt(ux * ux + uy * uy + uz * uz)
        a = reach[arm]
        d1 = 1.0 - max(d, 0.0) / m
        d2 = 1.0 - c / a
        phi += d1 * d2
        if d > 0.0:  # theirs: a gradient on the distance only when apart
            nx, ny, nz = _normal(table, k, centers, obstacle)
            ax, ay, az = table[k, 4], table[k, 5], table[k, 6]
            _subtract_point_gradient(out, d2 / m, nx, ny, nz, ax, ay, az, J_world, support, k)
        if c > 0.0:
            scale = d1 / (a * c)
            _subtract_point_gradient(out, scale, ux, uy, uz, cx, cy, cz, J_world, support, k)
    out[0] = phi
    return phi
