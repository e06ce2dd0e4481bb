"""The robot's kinematic and dynamic quantities at one instant, computed once with Pinocchio.

Holding a :class:`RobotState` means every quantity in it is current for its ``(q, v)``; the
constructor runs the kinematics (as pink's ``Configuration`` does). It is created once per 1 kHz
control step and shared by every task map and by the observation the outer loop sees.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from amex.robot import RobotModel
from amex.robot.geometry import cross

_LWA = pin.LOCAL_WORLD_ALIGNED


class RobotState:
    """Joint state plus everything the controller and the methods read from it.

    Attributes:
        q: joint positions, shape (7,) [rad].
        v: joint velocities, shape (7,) [rad/s].
        H: TCP pose in the world frame (homogeneous), shape (4, 4).
        y_list: the 6-D task state of the paper's methods as Python floats, (TCP position [m],
            TCP z-axis): the 1 kHz loop does its 3-vector arithmetic on these.
        y: the same as an array, shape (6,) (built on first use).
        tcp_pos: TCP position in the world frame, a view of ``y[:3]`` [m].
        tcp_axis: TCP z-axis in the world frame (unit), a view of ``y[3:]``.
        J: TCP Jacobian, LOCAL_WORLD_ALIGNED, rows (linear, angular), shape (6, 7).
        acc_drift: TCP classical acceleration at zero joint acceleration, rows (linear, angular),
            i.e. ``J_dot @ v`` (the term Eq. 5 needs when it maps q_ddot to task accelerations),
            shape (6,) [m/s^2, rad/s^2].
    """

    __slots__ = ("robot", "data", "q", "v", "H", "y_list", "_y", "J", "acc_drift")

    def __init__(self, robot: RobotModel, data: pin.Data, q: np.ndarray, v: np.ndarray) -> None:
        model = robot.model
        fid = robot.tcp_frame_id
        self.robot = robot
        self.data = data
        self.q = q
        self.v = v
        pin.forwardKinematics(model, data, q, v, robot.zero_velocity)
        pin.computeJointJacobians(model, data)
        self.H = pin.updateFramePlacement(model, data, fid).homogeneous
        H = self.H.tolist()
        self.y_list = [H[0][3], H[1][3], H[2][3], H[0][2], H[1][2], H[2][2]]
        self._y: np.ndarray | None = None
        self.J = pin.getFrameJacobian(model, data, fid, _LWA)
        self.acc_drift = pin.getFrameClassicalAcceleration(model, data, fid, _LWA).vector

    @property
    def y(self) -> np.ndarray:
        """Task state (TCP position [m], TCP z-axis), shape (6,)."""
        if self._y is None:
            self._y = np.array(self.y_list)
        return self._y

    @property
    def tcp_pos(self) -> np.ndarray:
        """TCP position in the world frame, shape (3,) [m]."""
        return self.y[:3]

    @property
    def tcp_axis(self) -> np.ndarray:
        """TCP z-axis in the world frame (unit), shape (3,)."""
        return self.y[3:]

    @property
    def tcp_vel(self) -> np.ndarray:
        """TCP linear velocity, shape (3,) [m/s]."""
        return self.J[:3] @ self.v

    @property
    def omega(self) -> np.ndarray:
        """TCP angular velocity, shape (3,) [rad/s]."""
        return self.J[3:] @ self.v

    @property
    def yd(self) -> np.ndarray:
        """Time derivative of :attr:`y`: (TCP velocity [m/s], omega x z [1/s]), shape (6,)."""
        return np.concatenate([self.tcp_vel, cross(self.omega, self.tcp_axis)])

    def mass_matrix(self) -> np.ndarray:
        """Joint-space mass matrix M(q) (full, symmetric), shape (7, 7) [kg m^2]."""
        M = pin.crba(self.robot.model, self.data, self.q)
        return np.triu(M) + np.triu(M, 1).T

    def bias_forces(self) -> np.ndarray:
        """Nonlinear effects h(q, v) = C(q, v) v + g(q), shape (7,) [N m]."""
        return pin.nonLinearEffects(self.robot.model, self.data, self.q, self.v).copy()
