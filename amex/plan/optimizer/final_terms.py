"""The four final terms of the trajectory cost and their Jacobian (TCP position, axis, rates).

At the last knot ``q_T`` (with ``v = (q_T - q_{T-1}) / dt``) the residuals are
``sqrt(w_pos) (p(q_T) - g)``, ``sqrt(w_vel) v`` (or the TCP velocity, the original's),
``sqrt(w_axis) (z(q_T) - a)`` and ``sqrt(w_axvel) J_z(q_T) v``; docs/planner.md gives f(x).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pinocchio as pin

from amex.plan.kinematics_kernels import final_terms_joint
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.robot.geometry import skew

__all__ = ["final_terms", "final_terms_numpy", "final_weights"]

_LWA = pin.LOCAL_WORLD_ALIGNED


def final_weights(costs: TrajectoryCosts) -> np.ndarray:
    """Square roots of the four final weights (position, velocity, axis, axis rate); read-only."""
    c = costs.weights
    return _square_roots(c.final_position, c.final_velocity, c.final_axis, c.final_axis_velocity)


@lru_cache(maxsize=16)
def _square_roots(*weights: float) -> np.ndarray:
    w = np.sqrt(list(weights))
    w.flags.writeable = False
    return w


def final_terms(
    model: pin.Model,
    data: pin.Data,
    fid: int,
    problem: TrajectoryProblem,
    q_prev: np.ndarray,
    q_last: np.ndarray,
    weights: np.ndarray | None = None,
    v: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of the four final terms, shape (m,), and their Jacobian, shape (m, 2n).

    The Jacobian columns are (q_{T-1}, q_T). Rows: position, joint velocity, axis, axis rate.
    The axis-rate derivative uses ``d omega / d q_i = z_i x sum_{k>i} z_k v_k`` (serial chain).
    With a joint final velocity (ours) the arithmetic is one compiled call
    (:func:`~amex.plan.kinematics_kernels.final_terms_joint`), bit for bit
    :func:`final_terms_numpy`, which the TCP velocity (the original's) uses; its two
    matrix-vector products are numpy's (``dot``, the BLAS call of ``@``, with less overhead).
    ``weights``: :func:`final_weights` of the problem's costs, ``v``: the final joint velocity
    ``(q_last - q_prev) / dt``, if already at hand.
    """
    c, dt, n = problem.costs, problem.dt, len(q_last)
    if c.final_velocity_space == "tcp":
        return final_terms_numpy(model, data, fid, problem, q_prev, q_last)
    pin.computeJointJacobians(model, data, q_last)
    oMf = pin.updateFramePlacement(model, data, fid)
    J = pin.getFrameJacobian(model, data, fid, _LWA)
    if v is None:
        v = (q_last - q_prev) / dt
    Jz = np.empty((3, n))
    residual = np.empty(9 + n)
    jac = np.empty((9 + n, 2 * n))
    w = final_weights(c) if weights is None else weights
    final_terms_joint(
        J,
        oMf.rotation,
        oMf.translation,
        v,
        J[3:].dot(v),
        problem.goal_pos,
        problem.goal_axis,
        w,
        float(dt),
        Jz,
        residual,
        jac,
    )
    np.multiply(Jz.dot(v), w[3], out=residual[6 + n :])  # w[3] (Jz @ v)
    return residual, jac


def final_terms_numpy(
    model: pin.Model,
    data: pin.Data,
    fid: int,
    problem: TrajectoryProblem,
    q_prev: np.ndarray,
    q_last: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`final_terms` in numpy (the reference of the compiled version; the original's)."""
    c, dt, n = problem.costs, problem.dt, len(q_last)
    pin.computeJointJacobians(model, data, q_last)
    oMf = pin.updateFramePlacement(model, data, fid)
    J = pin.getFrameJacobian(model, data, fid, _LWA)
    z = oMf.rotation[:, 2]
    Jw = J[3:]
    Jz = -skew(z) @ Jw
    v = (q_last - q_prev) / dt
    omega_after = np.cumsum((Jw * v)[:, ::-1], axis=1)[:, ::-1] - Jw * v  # sum_{k>i} z_k v_k
    domega = np.stack(
        [
            Jw[1] * omega_after[2] - Jw[2] * omega_after[1],
            Jw[2] * omega_after[0] - Jw[0] * omega_after[2],
            Jw[0] * omega_after[1] - Jw[1] * omega_after[0],
        ]
    )
    dzdot = -skew(z) @ domega + skew(Jw @ v) @ Jz
    w = final_weights(c)
    eye = np.eye(n) / dt
    p_last = oMf.translation
    if c.final_velocity_space == "tcp":  # (p(q_T) - p(q_{T-1})) / dt, as the original's
        p_last, z = p_last.copy(), z.copy()  # data is about to hold q_{T-1}
        J_last = J[:3].copy()
        pin.computeJointJacobians(model, data, q_prev)
        p_prev = pin.updateFramePlacement(model, data, fid).translation.copy()
        J_prev = pin.getFrameJacobian(model, data, fid, _LWA)[:3]
        vel, d_prev, d_last = (p_last - p_prev) / dt, -J_prev / dt, J_last / dt
    else:  # the joint velocity (q_T - q_{T-1}) / dt
        vel, d_prev, d_last = v, -eye, eye
    m = len(vel)
    residual = np.concatenate(
        [
            w[0] * (p_last - problem.goal_pos),
            w[1] * vel,
            w[2] * (z - problem.goal_axis),
            w[3] * (Jz @ v),
        ]
    )
    jac = np.zeros((9 + m, 2 * n))
    jac[0:3, n:] = w[0] * J[:3]
    jac[3 : 3 + m, :n], jac[3 : 3 + m, n:] = w[1] * d_prev, w[1] * d_last
    jac[3 + m : 6 + m, n:] = w[2] * Jz
    jac[6 + m :, :n], jac[6 + m :, n:] = -w[3] * Jz / dt, w[3] * (Jz / dt + dzdot)
    return residual, jac
