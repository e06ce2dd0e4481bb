"""Task maps of the operational-space controller (the rows of the paper's Eq. 5).

Each map ``phi(q)`` gives its value, its Jacobian ``J = d phi / d q`` and its drift ``J_dot v``, so
that ``phi_ddot = J q_ddot + J_dot v``. The controller asks each map to track the PD acceleration of
Eq. 6. Maps read a :class:`~amex.control.state.RobotState`, which already holds the kinematics.
"""

from __future__ import annotations

import abc
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.control.collision import CollisionModel
from amex.control.state import RobotState
from amex.core.compiled import kernel
from amex.core.errors import ConfigError
from amex.robot.geometry import cross, skew

_LWA = pin.LOCAL_WORLD_ALIGNED


class TaskTerms(NamedTuple):
    """Value, velocity, Jacobian and drift of a task map at one state.

    Attributes:
        phi: task value, shape (m,).
        phid: task velocity ``J v``, shape (m,).
        J: Jacobian, shape (m, n).
        drift: ``J_dot v``, shape (m,).
    """

    phi: np.ndarray
    phid: np.ndarray
    J: np.ndarray
    drift: np.ndarray


class TaskMap(abc.ABC):
    """A differentiable map from joint space to a task space, ``y = phi(q)``."""

    @abc.abstractmethod
    def evaluate(self, state: RobotState) -> TaskTerms:
        """Value, velocity, Jacobian and drift at ``state``."""


class PositionMap(TaskMap):
    """TCP position in the world frame, ``phi_pos(q)`` [m] (Eq. 5, first row)."""

    def evaluate(self, state: RobotState) -> TaskTerms:
        """See :class:`TaskMap`; the drift is the TCP's classical acceleration at q_ddot = 0."""
        return TaskTerms(state.tcp_pos, state.tcp_vel, state.J[:3], state.acc_drift[:3])


class AxisMap(TaskMap):
    """TCP z-axis in the world frame, ``phi_dir(q) = R(q) e_z`` (Eq. 5, second row).

    With angular velocity w = J_w v: ``z_dot = w x z = -[z]x J_w v`` and, at q_ddot = 0,
    ``z_ddot = a0 x z + w x (w x z)`` where ``a0 = J_w_dot v`` is the angular drift.
    """

    def evaluate(self, state: RobotState) -> TaskTerms:
        """See :class:`TaskMap`."""
        z, w = state.tcp_axis, state.omega
        J = -skew(z) @ state.J[3:]
        zd = cross(w, z)
        drift = cross(state.acc_drift[3:], z) + cross(w, zd)
        return TaskTerms(z, zd, J, drift)


class JointMap(TaskMap):
    """The joint vector itself, ``phi(q) = q`` (posture, damping and CR's joint targets)."""

    def __init__(self, nv: int) -> None:
        self._eye = np.eye(nv)
        self._zero = np.zeros(nv)

    def evaluate(self, state: RobotState) -> TaskTerms:
        """See :class:`TaskMap`."""
        return TaskTerms(state.q, state.v, self._eye, self._zero)


class CollisionMap(TaskMap):
    """Penetration of the safety margin, ``phi_col(q) = sum_k max(0, margin - d_k(q))`` [m].

    Ours (``controller.collision_cost=hinge``): the sum runs over the arm-obstacle pairs closer
    than ``margin`` (Eq. 5, third row). The authors' task had another value, their proxy cost
    (:class:`ProxyMap`). Its target is 0, so its PD acceleration pushes the arm out of the
    margin. ``d d_k / d q = n_k^T J_k`` with ``n_k`` the unit normal from the obstacle to the arm
    and ``J_k`` the linear Jacobian of the arm's witness point. The drift term (curvature of
    ``d_k``) is neglected: the hinge is not twice differentiable at the margin anyway.
    """

    def __init__(self, collision: CollisionModel, margin: float) -> None:
        self.collision = collision
        self.margin = float(margin)
        self._data: object = None
        self._J_world = np.zeros((6, collision.robot.nv))

    def _world_jacobians(self, state: RobotState) -> np.ndarray:
        """Pinocchio's world-frame joint Jacobians of ``state`` (a view of ``data.J``)."""
        if state.data is not self._data:
            self._data, self._J_world = state.data, state.data.J
        return self._J_world

    def terms_into(self, state: RobotState, out: np.ndarray) -> bool:
        """The compiled :meth:`evaluate`: ``out = (phi, J)``, shape (1 + n,); whether phi is on.

        Out of the margin (the common step) only ``out[0] = 0`` is written.
        """
        c = self.collision
        if c.update(state.data, state) >= self.margin:
            out[0] = 0.0
            return False
        if state.data is not self._data:
            self._data, self._J_world = state.data, state.data.J
        kernel("amex.control.collision_kernels", "hinge_terms")(
            out, c.table, self._J_world, c.support, c.pair_obstacle, c.centers, self.margin
        )
        return True

    def evaluate(self, state: RobotState) -> TaskTerms:
        """See :class:`TaskMap`; all-zero terms when no pair is inside the margin."""
        nv = state.v.shape[0]
        J = np.zeros((1, nv))
        phi = 0.0
        for prox in self.collision.proximities(state.data, self.margin):
            J_point = point_jacobian(state, prox.joint_id, prox.point)
            J[0] -= prox.normal @ J_point
            phi += self.margin - prox.distance
        phi_arr = np.array([phi])
        return TaskTerms(phi_arr, J @ state.v, J, np.zeros(1))


class ProxyMap(CollisionMap):
    """The authors' collision task: their proxy cost, dimensionless (``collision_cost=proxy``).

    ``phi(q) = sum_p (1 - d_p / m) (1 - c_p / a_p)`` over the arm-obstacle pairs p closer than
    the margin m, with ``c_p`` the distance between the two shapes' centres and
    ``a_p = m + 1.5 (r_arm + r_obstacle)``, the r their shapes' radii (the authors' swift mesh
    radii: the distance from a shape's centre to its farthest vertex; ``kinematicsProxyCost`` in
    their ``ors.cpp``, docs/controller.md). A penetrating pair counts with ``d_p = 0``, as their
    swift interface reported it.

    Jacobian (theirs): ``-(1 - c_p / a_p) / m * n_p^T J(x_p)`` while ``d_p > 0`` (x_p the arm's
    witness point, n_p the normal from the obstacle to the arm), plus
    ``-(1 - d_p / m) / a_p * u_p^T J(o_p)`` (o_p the arm shape's centre, u_p the unit vector from
    the obstacle's centre to it); the obstacle does not move with q. Drift neglected, as theirs.

    Args:
        collision: the arm-obstacle distance model.
        margin: m [m].
        arm_radii: radius of each arm shape, in the order of ``robot.capsules`` [m]; empty:
            each capsule's bounding radius ``half_length + radius`` (theirs: 0.3 for a link of
            the chain, 2e-4 for its TCP).
        obstacle_radius: the radius of every obstacle [m] (theirs: 0.1).

    Raises:
        ConfigError: ``arm_radii`` is neither empty nor one positive radius per capsule.
    """

    def __init__(
        self,
        collision: CollisionModel,
        margin: float,
        arm_radii: Sequence[float] = (),
        obstacle_radius: float = 0.1,
    ) -> None:
        super().__init__(collision, margin)
        caps = collision.robot.capsules
        radii = [c.half_length + c.radius for c in caps] if not len(arm_radii) else arm_radii
        if len(radii) != len(caps) or not all(r > 0.0 for r in radii):
            raise ConfigError.invalid(
                "controller.proxy_arm_radii",
                list(arm_radii),
                f"[] or {len(caps)} radii > 0 [m], one per arm capsule",
            )
        if not obstacle_radius > 0.0:
            raise ConfigError.invalid(
                "controller.proxy_obstacle_radius", obstacle_radius, "a radius > 0 [m]"
            )
        self.reach = [self.margin + 1.5 * (float(r) + obstacle_radius) for r in radii]  # a_p
        self.centers = [c.placement.translation.copy() for c in caps]  # in the joint frames
        self._reach = np.array(self.reach)

    def terms_into(self, state: RobotState, out: np.ndarray) -> bool:
        """See :meth:`CollisionMap.terms_into`."""
        c = self.collision
        if c.update(state.data, state) >= self.margin:
            out[0] = 0.0
            return False
        J_world = self._world_jacobians(state)
        kernel("amex.control.collision_kernels", "proxy_terms")(
            out, c.table, c.placements, J_world, c.support, c.pair_obstacle, c.pair_arm,
            c.centers, self._reach, self.margin,
        )  # fmt: skip
        return True

    def evaluate(self, state: RobotState) -> TaskTerms:
        """See :class:`TaskMap`; all-zero terms when no pair is inside the margin."""
        nv = state.v.shape[0]
        J = np.zeros((1, nv))
        phi, m = 0.0, self.margin
        for prox in self.collision.proximities(state.data, m):
            center = state.data.oMi[prox.joint_id].act(self.centers[prox.shape])
            away = center - self.collision.obstacle_center(prox.obstacle)
            c = float(np.sqrt(away @ away))
            a = self.reach[prox.shape]
            d1 = 1.0 - max(prox.distance, 0.0) / m
            d2 = 1.0 - c / a
            phi += d1 * d2
            Jj = pin.getJointJacobian(state.robot.model, state.data, prox.joint_id, _LWA)
            if prox.distance > 0.0:  # theirs: a gradient on the distance only when apart
                J[0] -= (d2 / m) * (prox.normal @ _point_rows(state, Jj, prox.joint_id, prox.point))
            if c > 0.0:
                J[0] -= (d1 / (a * c)) * (away @ _point_rows(state, Jj, prox.joint_id, center))
        phi_arr = np.array([phi])
        return TaskTerms(phi_arr, J @ state.v, J, np.zeros(1))


def _point_rows(state: RobotState, Jj: np.ndarray, joint_id: int, point: np.ndarray) -> np.ndarray:
    """Linear Jacobian (3, n) of a world ``point`` on joint ``joint_id`` from its ``Jj``."""
    r = point - state.data.oMi[joint_id].translation
    return Jj[:3] - skew(r) @ Jj[3:]


def point_jacobian(state: RobotState, joint_id: int, point: np.ndarray) -> np.ndarray:
    """Linear Jacobian (3, n) of the world ``point`` rigidly attached to joint ``joint_id``."""
    Jj = pin.getJointJacobian(state.robot.model, state.data, joint_id, _LWA)
    return _point_rows(state, Jj, joint_id, point)
