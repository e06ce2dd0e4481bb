"""The authors' collision term of CR's plans: their proxy cost, squared per knot (``mpc.cpp``).

Per knot t, one residual ``r_t = sqrt(w) sum_p (1 - d_p / m) (1 - c_p / a_p)`` over the
capsule-obstacle pairs p closer than the margin m (``collision_cost=proxy``): the value of their
``collTMT`` task map (``kinematicsProxyCost`` in ``ors.cpp``) at the target 0 and precision w, so
the cost is ``w (sum_p d1_p d2_p)^2``. ``c_p`` is the distance between the capsule's centre and
the obstacle's, ``a_p = m + 1.5 (r_capsule + r_obstacle)`` with each shape's bounding radius
(half length + radius for a capsule, the radius for a sphere: their swift mesh radii, 0.3 m for a
link of the chain, 2e-4 m for its TCP, 0.1 m for the obstacle). A penetrating pair counts with
``d_p = 0`` and moves its residual through ``c_p`` only, as their swift interface reported it.
Ours sums ``max(0, 1 - d / m)^2`` per pair instead (:func:`~.residuals.residuals`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from amex.plan.batch_kinematics import BatchKinematics, BatchPoses, CapsuleDistances
from amex.robot import RobotModel

__all__ = ["ProxyTerms", "center_distances", "proxy_jacobian", "proxy_terms"]


class ProxyTerms(NamedTuple):
    """The proxy residuals of a trajectory and what their Jacobian reuses.

    Attributes:
        residual: ``r_t`` per free knot, shape (T,).
        pairs: the pairs within the margin, (capsule, obstacle, knot), sorted by knot.
        d1: ``1 - max(d_p, 0) / m`` per pair, shape (P,).
        d2: ``1 - c_p / a_p`` per pair, shape (P,).
        reach: ``a_p`` per pair, shape (P,) [m].
        centers: the centre distances ``c`` (C, k, T) [m] and centre offsets (C, k, 3, T) [m].
    """

    residual: np.ndarray
    pairs: tuple[np.ndarray, np.ndarray, np.ndarray]
    d1: np.ndarray
    d2: np.ndarray
    reach: np.ndarray
    centers: CapsuleDistances


def center_distances(
    kin: BatchKinematics, poses: BatchPoses, obstacles: np.ndarray
) -> CapsuleDistances:
    """Distances between each capsule's centre and each obstacle's centre, at every knot.

    The offsets (centre of the capsule minus centre of the obstacle) take the place of
    :class:`CapsuleDistances`' closest-point offsets, so :meth:`BatchKinematics.distance_gradients`
    gives the centre distances' gradients.
    """
    ends = kin.cap_ends  # (C, 2, 3): segment start and start-to-end vector, turned frames
    middle = ends[:, 0] + 0.5 * ends[:, 1]  # (C, 3)
    joints = kin.cap_joint
    world = poses.position[joints] + np.einsum("cb,cbat->cat", middle, poses.rotation[joints])
    offset = world[:, None] - np.asarray(obstacles, dtype=float)[None, :, :, None]  # (C,k,3,T)
    return CapsuleDistances(np.sqrt(np.einsum("ckat,ckat->ckt", offset, offset)), offset)


def proxy_terms(
    robot: RobotModel,
    kin: BatchKinematics,
    poses: BatchPoses,
    dist: CapsuleDistances,
    obstacles: np.ndarray,
    obstacle_radii: np.ndarray,
    margin: float,
    weight: float,
) -> ProxyTerms:
    """The proxy residuals (module notes) of the knots in ``poses``, with distances ``dist``."""
    d = dist.distance  # (C, k, T)
    T = d.shape[2]
    knot, cap, obs = np.nonzero(d.transpose(2, 0, 1) < margin)  # sorted by knot
    centers = center_distances(kin, poses, obstacles)
    bound = np.array([c.half_length + c.radius for c in robot.capsules])
    reach = margin + 1.5 * (bound[cap] + np.asarray(obstacle_radii, dtype=float)[obs])
    d1 = 1.0 - np.maximum(d[cap, obs, knot], 0.0) / margin
    d2 = 1.0 - centers.distance[cap, obs, knot] / reach
    residual = np.zeros(T)
    np.add.at(residual, knot, d1 * d2)
    residual *= math.sqrt(weight)
    return ProxyTerms(residual, (cap, obs, knot), d1, d2, reach, centers)


def proxy_jacobian(
    kin: BatchKinematics,
    poses: BatchPoses,
    dist: CapsuleDistances,
    obstacles: np.ndarray,
    terms: ProxyTerms,
    margin: float,
    weight: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The knots with pairs in the margin, each once, and the gradients of their residuals.

    ``d r_t / d q_t = -sqrt(w) sum_p ((d2_p / m) [d_p > 0] grad d_p + (d1_p / a_p) grad c_p)``,
    the authors' Jacobian (``kinematicsProxyCost``).

    Returns:
        ``(rows, J)``: knot indices (U,) and their residuals' gradients, shape (U, n).
    """
    cap, obs, knot = terms.pairs
    grad_d = kin.distance_gradients(poses, dist, obstacles, terms.pairs)
    grad_c = kin.distance_gradients(poses, terms.centers, obstacles, terms.pairs)
    apart = dist.distance[cap, obs, knot] > 0.0
    pair = (np.where(apart, terms.d2 / margin, 0.0)[:, None] * grad_d) + (terms.d1 / terms.reach)[
        :, None
    ] * grad_c
    first = np.concatenate(([0], np.flatnonzero(knot[1:] != knot[:-1]) + 1))
    return knot[first], -math.sqrt(weight) * np.add.reduceat(pair, first, axis=0)
