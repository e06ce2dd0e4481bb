"""Damped least-squares inverse kinematics for the 6-D task (TCP position and z-axis).

Used to check that every benchmark goal is reachable with the top-down approach, and as a
deterministic initial guess. Joint limits are respected by clamping each iterate.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from amex.robot import RobotModel
from amex.robot.geometry import skew


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
    axis_weight: float = 1.0,
) -> IKResult:
    """Solve ``p_tcp(q) = goal_pos`` and ``z_tcp(q) = goal_axis`` by damped Gauss-Newton steps.

    Each step solves ``(J^T J + damping I) dq = J^T e`` with ``e`` the stacked position and axis
    errors and ``J`` their Jacobian (the axis rows are ``-[z]x J_w``, both weighted by
    ``axis_weight``; 0 solves for the position alone), then clamps to the limits (a joint whose
    limits span a full turn is wrapped into [-pi, pi) instead: the same pose).
    """
    model = robot.model
    data = model.createData()
    q = robot.q0.copy() if q_init is None else np.array(q_init, dtype=float)
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    turns = hi - lo >= 2.0 * np.pi  # joints that can turn all the way: wrapped, not clamped
    fid = robot.tcp_frame_id
    goal_pos = np.asarray(goal_pos, dtype=float)
    goal_axis = np.asarray(goal_axis, dtype=float)
    e = np.zeros(6)
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (reported below)
        pin.forwardKinematics(model, data, q)
        M = pin.updateFramePlacement(model, data, fid)
        z = M.rotation[:, 2]
        e = np.concatenate([goal_pos - M.translation, axis_weight * (goal_axis - z)])
        if np.linalg.norm(e) < tolerance:
            break
        J6 = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL_WORLD_ALIGNED)
        J = np.vstack([J6[:3], axis_weight * (-skew(z) @ J6[3:])])
        dq = np.linalg.solve(J.T @ J + damping * np.eye(model.nv), J.T @ e)
        q = q + dq
        q[turns] = np.mod(q[turns] + np.pi, 2.0 * np.pi) - np.pi
        q = np.clip(q, lo, hi)
    pin.forwardKinematics(model, data, q)
    M = pin.updateFramePlacement(model, data, fid)
    return IKResult(
        q=q,
        position_error=float(np.linalg.norm(goal_pos - M.translation)),
        axis_error=float(np.linalg.norm(goal_axis - M.rotation[:, 2])),
        iterations=iterations,
    )


def reach(
    robot: RobotModel, goal_pos: np.ndarray, goal_axis: np.ndarray, tolerance: float = 1e-4
) -> IKResult:
    """The best of :func:`solve_ik` from ``q0`` with the axis weighted 1, 0.1 and 0.

    The last solve has 10x the damping, which keeps a position-only solve out of a local minimum.

    The first solution within ``tolerance`` of both the position [m] and the axis is returned;
    otherwise the one closest in position: a goal whose axis the arm cannot take may still be
    reached in position (the success criterion of the benchmark).
    """
    results = []
    for weight, damping in ((1.0, 1e-3), (0.1, 1e-3), (0.0, 1e-2)):
        res = solve_ik(
            robot, goal_pos, goal_axis, damping=damping, max_iterations=500, axis_weight=weight
        )
        if res.position_error < tolerance and res.axis_error < tolerance:
            return res
        results.append(res)
    return min(results, key=lambda r: r.position_error)
