"""The control-barrier filter: a desired TCP velocity made safe by a QP over joint velocities.

One implementation for ``cbf_ik`` (greedy differential IK to the goal) and ``amex_cbf`` (AMEX's
targets): given the measured arm (:mod:`amex.methods.clearance`) and a nominal task velocity
``(v_p, v_z)`` (TCP linear velocity [m/s], TCP axis rate [1/s]), the joint velocity solves

    min_u  1/2 |J_p u - v_p|^2 + w_z/2 |J_z u - v_z|^2 + lambda/2 |u|^2
    s.t.   grad d_k u + dd_k/dt >= -gamma (d_k - d_s)       for every pair k with d_k < d_a
           max(-f v_max, -gamma_q (q - q_lo - b)) <= u <= min(f v_max, gamma_q (q_hi - b - q))

with ``J_z = -[z]x J_w`` the axis Jacobian. The pair rows are control-barrier constraints on
``h_k = d_k - d_s`` (Ames et al., ECC 2019, the linear class-K form ``h_dot >= -gamma h``), i.e.
Faverjon & Tournassoud's (1987) velocity damper; the joint bounds are the same barrier on the
distances to the buffered joint limits, capped at a fraction of the speed limits. Pairs beyond
the activation distance ``d_a`` are left out. The QP is built by :func:`build_barrier_qp` (pure)
and solved by :func:`solve_barrier_qp` with qpsolvers (DAQP, a dual active-set solver, by
default). When it is infeasible (several barriers against the joint limits) the pair rows are
relaxed by one slack ``sigma >= 0`` with cost ``slack_weight/2 sigma^2``. Derivation and the
choices: ``docs/methods/cbf_ik.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from amex.core.errors import SolverError
from amex.core.scaling import scaled
from amex.methods.base import invalid
from amex.methods.clearance import ArmSensor, ArmSnapshot
from amex.robot import RobotModel
from amex.robot.geometry import skew

#: Gradients shorter than this are no constraint (a capsule the joints cannot move) [m/rad].
MIN_GRADIENT = 1e-9
#: qpsolvers' solvers the filter accepts (DAQP is installed with amex).
SOLVERS = ("daqp", "quadprog", "osqp", "proxqp", "clarabel", "piqp")


@dataclass
class BarrierConfig:
    """The barrier filter's settings (shared by ``cbf_ik`` and ``amex_cbf``).

    Attributes:
        barrier_gain: gamma of ``h_dot >= -gamma h`` for the arm-obstacle pairs [1/s].
        safety_distance: d_s, the distance the barrier keeps [m] (original units).
        activation_distance: d_a, pairs at or beyond it get no constraint [m] (original units).
        limit_gain: gamma_q of the joint-limit barrier [1/s].
        limit_buffer: b, distance kept from each joint limit [rad].
        speed_fraction: f, the joint speed bound as a fraction of the speed limits [-].
        axis_weight: w_z, weight of the axis rate against the TCP velocity [m^2 x scale^2].
        regularization: lambda, weight of the joint speed [m^2/rad^2 x scale^2].
        slack_weight: cost of the slack of an infeasible QP [1/(m/s)^2 relative].
        solver: the qpsolvers solver.
    """

    barrier_gain: float = 5.0  # [1/s]
    safety_distance: float = field(default=0.05, metadata=scaled(1))  # [m] (Panda: 0.01)
    activation_distance: float = field(default=0.5, metadata=scaled(1))  # [m] (Panda: 0.1)
    limit_gain: float = 5.0  # [1/s]
    limit_buffer: float = 0.05  # [rad]
    speed_fraction: float = 0.5  # [-]
    axis_weight: float = field(default=1.0, metadata=scaled(2))  # [-] (Panda: 0.04)
    regularization: float = field(default=0.0025, metadata=scaled(2))  # [-] (Panda: 1e-4)
    slack_weight: float = 1e6  # [-]
    solver: str = "daqp"

    def validate(self) -> None:
        """Raise :class:`ConfigError` for filter settings that cannot run."""
        if self.solver not in SOLVERS:
            raise invalid("solver", self.solver, SOLVERS)
        for key in ("barrier_gain", "limit_gain", "speed_fraction", "regularization",
                    "slack_weight"):  # fmt: skip
            if not getattr(self, key) > 0.0:
                raise invalid(key, getattr(self, key), "> 0")
        if not self.activation_distance > self.safety_distance:
            raise invalid("activation_distance", self.activation_distance,
                          f"> safety_distance = {self.safety_distance:g}")  # fmt: skip


class BarrierQP(NamedTuple):
    """``min 1/2 u^T P u + c^T u  s.t.  G u <= h,  lb <= u <= ub`` (module notes).

    Attributes:
        P: shape (n, n), positive definite.
        c: shape (n,).
        G: the barrier rows, shape (k, n).
        h: shape (k,).
        lb: shape (n,) [rad/s].
        ub: shape (n,) [rad/s].
    """

    P: np.ndarray
    c: np.ndarray
    G: np.ndarray
    h: np.ndarray
    lb: np.ndarray
    ub: np.ndarray


class BarrierSolution(NamedTuple):
    """The filtered joint velocity and how it was found.

    Attributes:
        qd: joint velocity u, shape (n,) [rad/s].
        active: barrier rows at their bound (within 1e-9).
        slack: the slack of the relaxed QP (0 when the QP was feasible) [m/s].
    """

    qd: np.ndarray
    active: int
    slack: float


def task_jacobians(snap: ArmSnapshot) -> tuple[np.ndarray, np.ndarray]:
    """The TCP position Jacobian and the axis Jacobian ``-[z]x J_w``, shapes (3, n)."""
    J = snap.state.J
    return J[:3], -skew(snap.state.tcp_axis) @ J[3:]


def build_barrier_qp(
    snap: ArmSnapshot,
    v_task: np.ndarray,
    config: BarrierConfig,
    q_lo: np.ndarray,
    q_hi: np.ndarray,
    speed_limit: np.ndarray,
) -> BarrierQP:
    """The QP of the module notes at ``snap`` for the nominal ``v_task`` = (v_p, v_z), (6,).

    Args:
        snap: the measured arm, pairs within the activation distance.
        v_task: nominal TCP velocity [m/s] and axis rate [1/s], shape (6,).
        config: the filter's settings (scene units).
        q_lo: lower joint limits, shape (n,) [rad].
        q_hi: upper joint limits, shape (n,) [rad].
        speed_limit: joint speed limits, shape (n,) [rad/s].
    """
    Jp, Jz = task_jacobians(snap)
    n = Jp.shape[1]
    wz, lam = config.axis_weight, config.regularization
    P = Jp.T @ Jp + wz * (Jz.T @ Jz)
    P[np.diag_indices(n)] += lam
    c = -(Jp.T @ v_task[:3] + wz * (Jz.T @ v_task[3:6]))
    pairs = snap.pairs
    keep = np.einsum("ij,ij->i", pairs.gradient, pairs.gradient) > MIN_GRADIENT**2
    G = -pairs.gradient[keep]
    h = config.barrier_gain * (pairs.distance[keep] - config.safety_distance) + pairs.rate[keep]
    q = snap.state.q
    vmax = config.speed_fraction * speed_limit
    b = config.limit_buffer
    lb = np.maximum(-vmax, -config.limit_gain * (q - q_lo - b))
    ub = np.minimum(vmax, config.limit_gain * (q_hi - b - q))
    lb = np.minimum(lb, vmax)  # beyond a buffered limit: back at most at the speed bound
    ub = np.maximum(ub, -vmax)
    return BarrierQP(P, c, G, h, lb, ub)


def solve_barrier_qp(qp: BarrierQP, solver: str, slack_weight: float) -> BarrierSolution:
    """Solve ``qp``; relax its barrier rows by one slack if infeasible (module notes).

    Raises:
        SolverError: neither the QP nor its relaxation could be solved (carries the QP).
    """
    import qpsolvers  # imported by the runs that solve a QP (~40 ms of every other start-up)

    G, h = (qp.G, qp.h) if len(qp.h) else (None, None)
    u = qpsolvers.solve_qp(qp.P, qp.c, G, h, lb=qp.lb, ub=qp.ub, solver=solver)
    if u is not None and np.isfinite(u).all():
        active = int(np.sum(qp.G @ u >= qp.h - 1e-9)) if len(qp.h) else 0
        return BarrierSolution(u, active, 0.0)
    n, k = len(qp.c), len(qp.h)
    P = np.zeros((n + 1, n + 1))
    P[:n, :n], P[n, n] = qp.P, slack_weight
    G_s = np.hstack([qp.G, -np.ones((k, 1))])
    lb, ub = np.append(qp.lb, 0.0), np.append(qp.ub, np.inf)
    x = qpsolvers.solve_qp(P, np.append(qp.c, 0.0), G_s, qp.h, lb=lb, ub=ub, solver=solver)
    if x is None or not np.isfinite(x).all():
        raise SolverError(f"barrier QP infeasible even with a slack ({k} barrier rows)", qp)
    return BarrierSolution(x[:n], k, float(x[n]))


class BarrierFilter:
    """The filter of the module notes for one arm.

    Args:
        robot: the arm (kinematics, capsules, joint and speed limits).
        config: the filter's settings in scene units.
    """

    def __init__(self, robot: RobotModel, config: BarrierConfig) -> None:
        self.robot = robot
        self.config = config
        self.sensor = ArmSensor(robot)
        self.q_lo = np.asarray(robot.model.lowerPositionLimit, dtype=float)
        self.q_hi = np.asarray(robot.model.upperPositionLimit, dtype=float)
        self.speed_limit = np.asarray(robot.velocity_limit, dtype=float)
        self.last: BarrierSolution | None = None

    def reset(self) -> None:
        """Forget the last step."""
        self.sensor.reset()
        self.last = None

    def measure(self, t: float, q: np.ndarray, qd: np.ndarray, obstacles: np.ndarray,
                radii: np.ndarray) -> ArmSnapshot:  # fmt: skip
        """The arm at the measured state, pairs within the activation distance."""
        return self.sensor.measure(t, q, qd, obstacles, radii, self.config.activation_distance)

    def filter(self, snap: ArmSnapshot, v_task: np.ndarray) -> BarrierSolution:
        """The safe joint velocity for the nominal ``v_task`` at ``snap``."""
        c = self.config
        qp = build_barrier_qp(snap, v_task, c, self.q_lo, self.q_hi, self.speed_limit)
        self.last = solve_barrier_qp(qp, c.solver, c.slack_weight)
        return self.last
