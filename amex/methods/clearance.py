"""What the reactive methods measure of the arm at one outer step: TCP kinematics and clearance.

RMPflow's leaves (:mod:`amex.methods.rmpflow`) and the barrier filter
(:mod:`amex.methods.barrier`) need, at the measured ``(q, q_dot)``, the TCP's position, axis and
Jacobians (a :class:`~amex.control.state.RobotState`) and, for every arm-capsule/obstacle pair
closer than an activation distance, the signed distance ``d`` (coal, through
:class:`~amex.control.collision.CollisionModel`), its gradient and how obstacle motion changes it:

* gradient: ``dd/dq = n^T J_p`` with ``n`` the unit normal from the obstacle to the arm and
  ``J_p = J_v - [r]x J_w`` the linear Jacobian of the arm's witness point, ``r`` its offset from
  the joint origin (LOCAL_WORLD_ALIGNED joint Jacobian ``(J_v; J_w)``); the same for any point on
  the normal line, so the surface witness point serves;
* rate: ``dd/dt`` at ``q_dot = 0`` from the obstacle's velocity ``v_o``, ``-n^T v_o``, where
  ``v_o`` is the finite difference of the perceived centres between two outer steps (0 at the
  first step and for static obstacles);
* drift (on request): ``d_ddot`` at ``q_ddot = 0`` with the obstacle moving at constant velocity
  ``v_o``, exact for a capsule's cylinder and its caps alike: ``d = rho - r_arm - r_o`` with
  ``rho = |m|`` the distance of the obstacle's centre ``c`` from the capsule's axis, ``m = P e``,
  ``e = p - c``, ``P = I - u u^T`` on the cylinder (``u`` the axis direction, ``p`` the axis point
  nearest to ``c``, taken as a point fixed on its link) and ``P = I`` at a cap (``p`` the cap's
  centre). With ``u_dot = w x u`` and ``e_dot = v_p - v_o``, ``e_ddot = a_p`` (the point's
  classical acceleration): ``m_dot = P e_dot - u (u_dot . e)``, ``n . m_ddot = n . a_p -
  2 (n . u_dot)(u . e_dot + u_dot . e)`` (``u . e = 0`` and ``n . u = 0`` on the cylinder) and
  ``d_ddot = (|m_dot|^2 - (n . m_dot)^2) / rho + n . m_ddot``, ``n = m / rho``
  (``tests/methods/test_reactive.py`` checks it against second differences of coal's distances).

Distances, normals and witness points come from one ``pin.computeDistances`` call over every
pair (:meth:`~amex.control.collision.CollisionModel.proximities`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.control.collision import CollisionModel
from amex.control.state import RobotState
from amex.core.compiled import kernel
from amex.core.types import require_finite
from amex.robot import RobotModel

_LWA = pin.LOCAL_WORLD_ALIGNED


class PairTerms(NamedTuple):
    """The arm-obstacle pairs within the activation distance, one row each.

    Attributes:
        distance: signed distances d, shape (k,) [m].
        gradient: ``dd/dq``, shape (k, n) [m/rad].
        rate: ``dd/dt`` from obstacle motion alone, shape (k,) [m/s].
        drift: ``d_ddot`` at ``q_ddot = 0`` (zeros unless asked for), shape (k,) [m/s^2].
        obstacle: the obstacle of each pair, shape (k,).
    """

    distance: np.ndarray
    gradient: np.ndarray
    rate: np.ndarray
    drift: np.ndarray
    obstacle: np.ndarray


class ArmSnapshot(NamedTuple):
    """The arm at one outer step.

    Attributes:
        state: kinematics at the measured ``(q, q_dot)`` (TCP pose, Jacobian, drift).
        pairs: the arm-obstacle pairs within the activation distance.
    """

    state: RobotState
    pairs: PairTerms


def no_pairs(n: int) -> PairTerms:
    """An empty :class:`PairTerms` for an ``n``-joint arm."""
    empty = np.zeros(0)
    return PairTerms(empty, np.zeros((0, n)), empty, empty, np.zeros(0, dtype=int))


class ArmSensor:
    """Measures :class:`ArmSnapshot` s of one arm, step after step (module notes).

    Args:
        robot: the arm.
    """

    def __init__(self, robot: RobotModel) -> None:
        self.robot = robot
        self.data = robot.model.createData()
        self._collision: CollisionModel | None = None
        self._radii: tuple[float, ...] = ()
        self._axes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the previous step (the obstacles' velocities start at 0)."""
        self._t_prev = math.nan
        self._centers_prev: np.ndarray | None = None

    def collision_model(self, radii: np.ndarray) -> CollisionModel | None:
        """The distance model for obstacles of ``radii`` (built again when they change)."""
        key = tuple(float(r) for r in radii)
        if not key:
            return None
        if self._collision is None or key != self._radii:
            self._collision, self._radii = CollisionModel(self.robot, key), key
            self.reset()
        return self._collision

    def obstacle_velocities(self, t: float, centers: np.ndarray) -> np.ndarray:
        """Finite-difference velocities of the obstacle centres, shape (k, 3) [m/s]."""
        prev, dt = self._centers_prev, t - self._t_prev
        if prev is None or prev.shape != centers.shape or not dt > 0.0:
            velocity = np.zeros_like(centers)
        else:
            velocity = (centers - prev) / dt
        self._centers_prev, self._t_prev = centers.copy(), t
        return velocity

    def measure(
        self,
        t: float,
        q: np.ndarray,
        qd: np.ndarray,
        centers: np.ndarray,
        radii: np.ndarray,
        activation: float,
        drift: bool = False,
    ) -> ArmSnapshot:
        """The arm at ``(q, q_dot)`` among spheres ``centers`` (k, 3) [m] of ``radii`` (k,) [m].

        Args:
            t: time of the measurement [s] (for the obstacles' velocities).
            q: joint positions, shape (n,) [rad].
            qd: joint velocities, shape (n,) [rad/s].
            centers: obstacle centres, shape (k, 3) [m].
            radii: obstacle radii, shape (k,) [m].
            activation: pairs at or beyond this distance are left out [m].
            drift: also compute each pair's ``d_ddot`` at ``q_ddot = 0``.

        Raises:
            InputError: a NaN or an infinity in the inputs (nothing is changed).
        """
        require_finite(q=q, qd=qd, obstacles=centers, obstacle_radii=radii)
        robot = self.robot
        state = RobotState(robot, self.data, q, qd)
        collision = self.collision_model(radii)
        if collision is None:
            return ArmSnapshot(state, no_pairs(robot.nv))
        centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        velocity = self.obstacle_velocities(t, centers)
        collision.set_obstacles(centers)
        found = collision.proximities(self.data, activation)
        k, n = len(found), robot.nv
        if not k:
            return ArmSnapshot(state, no_pairs(n))
        model, data = robot.model, self.data
        index: dict[int, int] = {}
        rows = np.array([index.setdefault(p.joint_id, len(index)) for p in found], dtype=np.int64)
        joints = list(index)
        u = len(joints)
        rotation, origin = np.empty((u, 3, 3)), np.empty((u, 3))
        jacobian = np.empty((u, 6, n))
        v_local, a_local = np.zeros((u, 6)), np.zeros((u, 6))
        for m, j in enumerate(joints):
            M = data.oMi[j]
            rotation[m], origin[m] = M.rotation, M.translation
            jacobian[m] = pin.getJointJacobian(model, data, j, _LWA)
            if drift:
                v_local[m], a_local[m] = data.v[j].vector, data.a[j].vector
        normal = np.array([p.normal for p in found])
        point = np.array([p.point for p in found])
        distance = np.array([p.distance for p in found])
        obstacle = np.array([p.obstacle for p in found], dtype=np.int64)
        shapes = np.array([p.shape for p in found], dtype=np.int64)
        offset, axis, half = self._shape_axes
        gradient, rate, accel = np.empty((k, n)), np.empty(k), np.zeros(k)
        terms = kernel("amex.methods.clearance_kernels", "pair_terms")
        terms(rows, rotation, origin, jacobian, v_local, a_local, normal, point,
              centers[obstacle], velocity[obstacle], offset[shapes], axis[shapes],
              half[shapes], drift, gradient, rate, accel)  # fmt: skip
        return ArmSnapshot(state, PairTerms(distance, gradient, rate, accel, obstacle))

    @property
    def _shape_axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every arm capsule's axis centre and direction in its joint frame, and half length."""
        if self._axes is None:
            caps = self.robot.capsules
            self._axes = (
                np.array([c.placement.translation for c in caps]),
                np.array([c.placement.rotation[:, 2] for c in caps]),
                np.array([c.half_length for c in caps]),
            )
        return self._axes
