"""Damped least-squares inverse kinematics for the 6-D task (TCP position and z-axis).

Used to check that every benchmark goal is reachable with the top-down approach, and as a
deterministic initial guess. Joint limits are respected by clamping each iterate.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.control.state import skew
from amex.robot import RobotModel


class IKResult(NamedTuple):
    """Outcome of :func:`solve_ik`.

    Attributes:
        q: final configuration, shape (7,) [rad].
        position_error: TCP position error [m].
        axis_error: norm of the TCP z-axis error (unit-vector difference) [-].
        iterations: iterations used.
    """

    q: np.ndarray
    position_error: float
    axis_error: float
    iterations: int


def solve_ik(
    robot: RobotModel,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    q_init: np.ndarray | None = None,
    damping: float = 1e-3,
    max_iterations: int = 200,
    tolerance: float = 1e-5,
) -> IKResult:
    """Solve ``p_tcp(q) = goal_pos`` and ``z_tcp(q) = goal_axis`` by damped Gauss-Newton steps.

    Each step solves ``(J^T J + damping I) dq = J^T e`` with ``e`` the stacked position and axis
    errors and ``J`` their Jacobian (the axis rows are ``-[z]x J_w``), then clamps to the limits.
    """
    model = robot.model
    data = model.createData()
    q = robot.q0.copy() if q_init is None else np.array(q_init, dtype=float)
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    fid = robot.tcp_frame_id
    goal_pos = np.asarray(goal_pos, dtype=float)
    goal_axis = np.asarray(goal_axis, dtype=float)
    e = np.zeros(6)
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (reported below)
        pin.forwardKinematics(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        z = M.rotation[:, 2]
        e = np.concatenate([goal_pos - M.translation, goal_axis - z])
        if np.linalg.norm(e) < tolerance:
            break
        J6 = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        J = np.vstack([J6[:3], -skew(z) @ J6[3:]])
        dq = np.linalg.solve(J.T @ J + damping * np.eye(model.nv), J.T @ e)
        q = np.clip(q + dq, lo, hi)
    pin.forwardKinematics(model, data, q)
    M = pin.updateFramePlacement(model, data, fid)
    return IKResult(
        q=q,
        position_error=float(np.linalg.norm(goal_pos - M.translation)),
        axis_error=float(np.linalg.norm(goal_axis - M.rotation[:, 2])),
        iterations=iterations,
    )
