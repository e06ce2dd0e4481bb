"""The robot's kinematic and dynamic quantities at one instant, computed once with Pinocchio.

Holding a :class:`RobotState` means every quantity in it is current for its ``(q, v)``; the
constructor runs the kinematics (as pink's ``Configuration`` does). It is created once per 1 kHz
control step and shared by every task map and by the observation the outer loop sees.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from amex.robot import RobotModel

_LWA = pin.LOCAL_WORLD_ALIGNED


def skew(w: np.ndarray) -> np.ndarray:
    """Cross-product matrix: ``skew(w) @ x == w x x``, shape (3, 3)."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` for 3-vectors, without ``np.cross``'s ~20 us of overhead."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


class RobotState:
    """Joint state plus everything the controller and the methods read from it.

    Attributes:
        q: joint positions, shape (7,) [rad].
        v: joint velocities, shape (7,) [rad/s].
        M: joint-space mass matrix (full, symmetric), shape (7, 7) [kg m^2].
        h: nonlinear effects C(q, v) v + g(q), shape (7,) [N m].
        tcp_pos: TCP position in the world frame, shape (3,) [m].
        tcp_axis: TCP z-axis in the world frame (unit), shape (3,).
        J: TCP Jacobian, LOCAL_WORLD_ALIGNED, rows (linear, angular), shape (6, 7).
        tcp_vel: TCP linear velocity, shape (3,) [m/s].
        omega: TCP angular velocity, shape (3,) [rad/s].
        acc_drift: TCP classical acceleration at zero joint acceleration, rows (linear, angular),
            i.e. ``J_dot @ v`` (the term Eq. 5 needs when it maps q_ddot to task accelerations),
            shape (6,) [m/s^2, rad/s^2].
    """

    __slots__ = (
        "robot", "data", "q", "v", "M", "h", "tcp_pos", "tcp_axis", "J", "tcp_vel", "omega",
        "acc_drift",
    )

    def __init__(self, robot: RobotModel, data: pin.Data, q: np.ndarray, v: np.ndarray) -> None:
        model = robot.model
        fid = robot.tcp_frame_id
        self.robot = robot
        self.data = data
        self.q = q
        self.v = v
        pin.computeAllTerms(model, data, q, v)
        M = data.M
        self.M = np.triu(M) + np.triu(M, 1).T
        self.h = data.nle.copy()
        pin.forwardKinematics(model, data, q, v, np.zeros_like(v))
        oMf = pin.updateFramePlacement(model, data, fid)
        self.tcp_pos = oMf.translation.copy()
        self.tcp_axis = oMf.rotation[:, 2].copy()
        self.J = pin.getFrameJacobian(model, data, fid, _LWA)
        twist = self.J @ v
        self.tcp_vel = twist[:3]
        self.omega = twist[3:]
        self.acc_drift = pin.getFrameClassicalAcceleration(model, data, fid, _LWA).vector

    @property
    def y(self) -> np.ndarray:
        """The 6-D task state of the paper's methods: (TCP position [m], TCP z-axis), shape (6,)."""
        return np.concatenate([self.tcp_pos, self.tcp_axis])

    @property
    def yd(self) -> np.ndarray:
        """Time derivative of :attr:`y`: (TCP velocity [m/s], omega x z [1/s]), shape (6,)."""
        return np.concatenate([self.tcp_vel, cross(self.omega, self.tcp_axis)])
