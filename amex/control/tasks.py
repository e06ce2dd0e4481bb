"""Task maps of the operational-space controller (the rows of the paper's Eq. 5).

Each map ``phi(q)`` gives its value, its Jacobian ``J = d phi / d q`` and its drift ``J_dot v``, so
that ``phi_ddot = J q_ddot + J_dot v``. The controller asks each map to track the PD acceleration of
Eq. 6. Maps read a :class:`~amex.control.state.RobotState`, which already holds the kinematics.
"""

from __future__ import annotations

import abc
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.control.collision import CollisionModel
from amex.control.state import RobotState
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

    The sum runs over the arm-obstacle pairs closer than ``margin`` (Eq. 5, third row; the original
    summed the same hinge over all proximity pairs). Its target is 0, so its PD acceleration pushes
    the arm out of the margin. ``d d_k / d q = n_k^T J_k`` with ``n_k`` the unit normal from the
    obstacle to the arm and ``J_k`` the linear Jacobian of the arm's witness point. The drift term
    (curvature of ``d_k``) is neglected: the hinge is not twice differentiable at the margin anyway.
    """

    def __init__(self, collision: CollisionModel, margin: float) -> None:
        self.collision = collision
        self.margin = float(margin)

    def evaluate(self, state: RobotState) -> TaskTerms:
        """See :class:`TaskMap`; all-zero terms when no pair is inside the margin."""
        nv = state.v.shape[0]
        J = np.zeros((1, nv))
        phi = 0.0
        for prox in self.collision.proximities(state.data, self.margin):
            Jj = pin.getJointJacobian(
                state.robot.model, state.data, prox.joint_id, _LWA
            )  # at the joint origin, world-aligned
            r = prox.point - state.data.oMi[prox.joint_id].translation
            J_point = Jj[:3] - skew(r) @ Jj[3:]
            J[0] -= prox.normal @ J_point
            phi += self.margin - prox.distance
        phi_arr = np.array([phi])
        return TaskTerms(phi_arr, J @ state.v, J, np.zeros(1))
