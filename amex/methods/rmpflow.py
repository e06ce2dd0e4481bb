"""RMPflow (Cheng et al., WAFR 2018; Ratliff et al. 2018): leaf policies pulled back and resolved.

Each outer step, at the measured ``(q, q_dot)``, every leaf i on its task space ``x_i = psi_i(q)``
(Jacobian ``J_i``, drift ``J_dot_i q_dot``) gives a canonical RMP ``(M_i, a_i)``
(:mod:`amex.methods.rmpflow_leaves`); they are pulled back to the joint space and resolved
(Cheng et al., Eq. 9-11: pushforward, pullback, resolve):

    f = sum_i J_i^T M_i (a_i - J_dot_i q_dot),   M = sum_i J_i^T M_i J_i,   q_ddot = M^+ f

with the pseudo-inverse ``M^+`` (``M^-1`` by Cholesky: the damping leaf's constant metric
makes M positive definite; the pseudo-inverse only if the factorization fails). The leaves: the
TCP position's goal attractor (``x = p_tcp``, Pinocchio's frame Jacobian and classical
acceleration), the TCP axis attractor (``x = z``, ``J = -[z]x J_w``), one obstacle leaf per
arm-capsule/obstacle pair within ``obstacle_radius``
(``x = d``, coal distances, :mod:`amex.methods.clearance`), two joint-limit leaves per joint
(``x = q_hi - b - q`` and ``q - q_lo - b``), the default configuration (``x = q - q0``) and the
joint-velocity damping (``x = q``).

The command is the resolved motion over the held outer period ``dt``, from the measured state:
``q(t + s) = q + q_dot s + q_ddot s^2 / 2``, sent as CR's joint targets are (the middle of the
period and the mean velocity over it): ``q* = q(t + dt/2)``, ``q_dot* = q_dot + q_ddot dt / 2``,
tracked by the inner controller's joint task (``controller.joint``). Why joint targets, and which
inner tasks act on them: ``docs/methods/rmpflow.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from amex.core.compiled import kernel
from amex.core.scaling import scaled
from amex.core.types import Command, Observation, require_finite
from amex.methods import rmpflow_leaves as leaves
from amex.methods.base import Method, MethodConfig, invalid
from amex.methods.clearance import ArmSensor, ArmSnapshot
from amex.robot.geometry import cross, skew

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


@dataclass
class RMPflowConfig(MethodConfig):
    """RMPflow's leaves; lengths in original units (x ``scenario.scale``, :mod:`amex.core.scaling`).

    The defaults are rmp2's hand-tuned Franka values (metres there; here the Panda's scene, scale
    0.2) but for the tuned ones (``docs/methods/rmpflow.md``); task-space metrics carry
    scale^-2, so that their weight against the joint-space leaves is the same on every scene.

    Attributes:
        pos: unused (RMPflow sends joint targets, tracked with ``controller.joint``).
        dir: unused.
        goal_gain: largest pull of the goal attractor [m/s^2] (original units).
        goal_damping: damping of the goal attractor [1/s].
        goal_softness: distance below which the pull is linear in the error [m].
        goal_metric: the goal metric near the goal, all directions [1/m^2 x scale^2].
        goal_metric_min: the goal metric far away, along the way to the goal [1/m^2 x scale^2].
        goal_metric_length: length over which the metric turns from all directions to one [m].
        goal_metric_alpha: the all-directions share of the metric far away [-].
        goal_boost: metric factor at the goal [-].
        goal_boost_length: length of the boost [m].
        axis_gain: stiffness of the TCP axis attractor [1/s^2].
        axis_damping: damping of the axis attractor [1/s].
        axis_metric: metric of the axis attractor [-].
        obstacle_margin: distance treated as contact [m].
        obstacle_gain: largest repulsion [m/s^2].
        obstacle_gain_length: decay length of the repulsion [m].
        obstacle_damping: gain of the approach braking [1/s].
        obstacle_damping_length: length scale of the braking [m].
        obstacle_damping_eps: regularizer of the braking's divisor [-].
        obstacle_velocity_gate: approach speed scale of the gate [m/s].
        obstacle_radius: distance at which an obstacle leaf vanishes (farther pairs left out) [m].
        obstacle_metric: metric scale of the obstacle leaves [1/m^2 x scale^2].
        obstacle_metric_length: length scale of the obstacle metric [m].
        obstacle_metric_eps: regularizer of the obstacle metric's divisor [-].
        limit_buffer: distance kept from each joint limit [rad].
        limit_metric: joint-limit metric scale [-].
        limit_metric_length: its length scale [rad].
        limit_metric_eps: regularizer of its divisor [-].
        limit_velocity_gate: speed scale of its gate [rad/s].
        limit_damping: joint-limit damping [1/s].
        limit_gain: joint-limit repulsion [rad/s^2].
        limit_gain_length: length scale of the repulsion [rad].
        limit_gain_eps: regularizer of the repulsion [-].
        posture_gain: stiffness of the default-configuration leaf [1/s^2].
        posture_damping: its damping [1/s].
        posture_limit: joint error at which its pull saturates [rad].
        posture_metric: its metric [-].
        damping_gain: joint-velocity damping gain, ``a = -gain |q_dot| q_dot`` [1/rad].
        damping_metric: metric per unit speed of the damping leaf [s/rad].
        damping_inertia: constant metric of the damping leaf [-].
        rcond: relative cut-off of the pseudo-inverse's singular values [-].
    """

    name: str = "rmpflow"
    goal_gain: float = field(default=250.0, metadata=scaled(1))  # [m/s^2] (Panda: 50)
    goal_damping: float = 70.0  # [1/s]
    goal_softness: float = field(default=0.375, metadata=scaled(1))  # [m] (Panda: 0.075)
    goal_metric: float = field(default=0.04, metadata=scaled(-2))  # [-] (Panda: 1)
    goal_metric_min: float = field(default=0.02, metadata=scaled(-2))  # [-] (Panda: 0.5)
    goal_metric_length: float = field(default=0.25, metadata=scaled(1))  # [m] (Panda: 0.05)
    goal_metric_alpha: float = 0.03  # [-]
    goal_boost: float = 3.0  # [-]
    goal_boost_length: float = field(default=0.1, metadata=scaled(1))  # [m] (Panda: 0.02)
    axis_gain: float = 50.0  # [1/s^2]
    axis_damping: float = 20.0  # [1/s]
    axis_metric: float = 0.04  # [-]
    obstacle_margin: float = field(default=0.0, metadata=scaled(1))  # [m]
    obstacle_gain: float = field(default=4000.0, metadata=scaled(1))  # [m/s^2] (Panda: 800)
    obstacle_gain_length: float = field(default=0.05, metadata=scaled(1))  # [m] (Panda: 0.01)
    obstacle_damping: float = 50.0  # [1/s]
    obstacle_damping_length: float = field(default=0.2, metadata=scaled(1))  # [m] (Panda: 0.04)
    obstacle_damping_eps: float = 0.01  # [-]
    obstacle_velocity_gate: float = field(default=0.05, metadata=scaled(1))  # [m/s]
    obstacle_radius: float = field(default=2.5, metadata=scaled(1))  # [m] (Panda: 0.5)
    obstacle_metric: float = field(default=0.04, metadata=scaled(-2))  # [-] (Panda: 1)
    obstacle_metric_length: float = field(default=0.1, metadata=scaled(1))  # [m] (Panda: 0.02)
    obstacle_metric_eps: float = 0.001  # [-]
    limit_buffer: float = 0.01  # [rad]
    limit_metric: float = 0.1  # [-]
    limit_metric_length: float = 0.01  # [rad]
    limit_metric_eps: float = 0.001  # [-]
    limit_velocity_gate: float = 0.01  # [rad/s]
    limit_damping: float = 200.0  # [1/s]
    limit_gain: float = 1.0  # [rad/s^2]
    limit_gain_length: float = 0.1  # [rad]
    limit_gain_eps: float = 0.01  # [-]
    posture_gain: float = 100.0  # [1/s^2]
    posture_damping: float = 50.0  # [1/s]
    posture_limit: float = 0.5  # [rad]
    posture_metric: float = 0.005  # [-]
    damping_gain: float = 30.0  # [1/rad]
    damping_metric: float = 0.005  # [s/rad]
    damping_inertia: float = 0.3  # [-]
    rcond: float = 1e-10  # [-]

    def validate(self) -> None:
        """Raise :class:`ConfigError` for settings RMPflow cannot run with."""
        for key in ("goal_softness", "goal_metric_length", "goal_boost_length",
                    "obstacle_gain_length", "obstacle_damping_length", "obstacle_velocity_gate",
                    "obstacle_radius", "obstacle_metric_length", "limit_metric_length",
                    "limit_velocity_gate", "limit_gain_length", "posture_limit"):  # fmt: skip
            if not getattr(self, key) > 0.0:
                raise invalid(key, getattr(self, key), "> 0")
        if not self.goal_metric_alpha <= 1.0:
            raise invalid("goal_metric_alpha", self.goal_metric_alpha, "in [0, 1]")
        if not self.goal_boost >= 1.0:
            raise invalid("goal_boost", self.goal_boost, ">= 1")
        if not (self.obstacle_metric_eps > 0.0 and self.limit_metric_eps > 0.0
                and self.limit_gain_eps > 0.0 and self.obstacle_damping_eps > 0.0):  # fmt: skip
            raise invalid("obstacle_metric_eps, limit_metric_eps, limit_gain_eps, "
                          "obstacle_damping_eps", "0", "> 0")  # fmt: skip
        if not self.damping_inertia + self.posture_metric > 0.0:
            raise invalid("damping_inertia", self.damping_inertia,
                          "> 0 (or posture_metric > 0): the summed metric must be invertible")


class Resolved(NamedTuple):
    """The pulled-back and resolved RMP of one step.

    Attributes:
        qdd: ``q_ddot = M^+ f``, shape (n,) [rad/s^2].
        metric: the summed metric ``M``, shape (n, n).
        force: the summed force ``f``, shape (n,).
    """

    qdd: np.ndarray
    metric: np.ndarray
    force: np.ndarray


class RMPflow(Method):
    """RMPflow with the leaves of the module notes, as joint targets for the inner controller.

    Args:
        plan: the reference plan; only its goal's axis is not used (the goal comes with each
            observation). RMPflow does not follow the reference.
        config: :class:`RMPflowConfig` (None: the defaults; scene units when built by a run).
        dt: outer (control) period [s].
        robot: the arm (kinematics, capsules, joint limits); required.
    """

    name = "rmpflow"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = RMPflowConfig
    needs_robot = True
    config: RMPflowConfig
    robot: RobotModel

    def __init__(
        self,
        plan: ReferencePlan,
        config: RMPflowConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        c = self.config
        self.sensor = ArmSensor(self.robot)
        model = self.robot.model
        self.q_lo = np.asarray(model.lowerPositionLimit, dtype=float) + c.limit_buffer
        self.q_hi = np.asarray(model.upperPositionLimit, dtype=float) - c.limit_buffer
        self.q_rest = self.robot.q0.copy()
        self._goal = (c.goal_gain, c.goal_damping, c.goal_softness, c.goal_metric,
                      c.goal_metric_min, c.goal_metric_length, c.goal_metric_alpha, c.goal_boost,
                      c.goal_boost_length)  # fmt: skip
        self._obstacle = (c.obstacle_margin, c.obstacle_gain, c.obstacle_gain_length,
                          c.obstacle_damping, c.obstacle_damping_length, c.obstacle_damping_eps,
                          c.obstacle_velocity_gate, c.obstacle_radius, c.obstacle_metric,
                          c.obstacle_metric_length, c.obstacle_metric_eps)  # fmt: skip
        self._limit = (c.limit_metric, c.limit_metric_length, c.limit_metric_eps,
                       c.limit_velocity_gate, c.limit_damping, c.limit_gain, c.limit_gain_length,
                       c.limit_gain_eps)  # fmt: skip
        self._params = tuple(np.array(p, dtype=float) for p in (
            self._goal, (c.axis_gain, c.axis_damping, c.axis_metric), self._obstacle,
            self._limit, (c.posture_gain, c.posture_damping, c.posture_limit, c.posture_metric),
            (c.damping_gain, c.damping_metric, c.damping_inertia)))  # fmt: skip
        self._last: Resolved | None = None
        self._pairs = 0

    # ----------------------------------------------------------------------------- policy
    def resolve(self, snap: ArmSnapshot, goal: np.ndarray) -> Resolved:
        """Pull every leaf back to the joint space and resolve (module notes), compiled.

        The same formulas as :meth:`resolve_leaves` in one call
        (:func:`amex.methods.rmpflow_kernels.resolve`); the pseudo-inverse if the Cholesky
        factorization of the metric fails.

        Args:
            snap: the arm at the measured state (pairs within ``obstacle_radius``, with drift).
            goal: TCP goal position and axis, shape (6,).
        """
        state, pairs = snap.state, snap.pairs
        n = len(state.q)
        A, b, qdd = np.empty((n, n)), np.empty(n), np.empty(n)
        resolve = kernel("amex.methods.rmpflow_kernels", "resolve")
        ok = resolve(state.J, state.y, state.acc_drift, state.q, state.v,
                     np.asarray(goal, dtype=float), self.q_lo, self.q_hi, self.q_rest,
                     pairs.distance, pairs.gradient, pairs.rate, pairs.drift,
                     *self._params, A, b, qdd)  # fmt: skip
        if not ok:
            qdd = np.linalg.pinv(A, rcond=self.config.rcond, hermitian=True) @ b
        return Resolved(qdd, A, b)

    def resolve_leaves(self, snap: ArmSnapshot, goal: np.ndarray) -> Resolved:
        """Pull every leaf back to the joint space and resolve (module notes), leaf by leaf.

        The readable form (:mod:`amex.methods.rmpflow_leaves`) that :meth:`resolve` compiles.

        Args:
            snap: the arm at the measured state (pairs within ``obstacle_radius``, with drift).
            goal: TCP goal position and axis, shape (6,).
        """
        c, state = self.config, snap.state
        q, qd = state.q, state.v
        n = len(q)
        A = np.zeros((n, n))
        b = np.zeros(n)
        J = state.J
        # goal attractor on the TCP position
        Jp = J[:3]
        rmp = leaves.goal_attractor(goal[:3] - state.tcp_pos, Jp @ qd, *self._goal)
        MJ = rmp.metric @ Jp
        A += Jp.T @ MJ
        b += Jp.T @ (rmp.metric @ (rmp.accel - state.acc_drift[:3]))
        # axis attractor on the TCP z-axis
        z, w = state.tcp_axis, J[3:] @ qd
        Jz = -skew(z) @ J[3:]
        zd = cross(w, z)
        z_drift = cross(state.acc_drift[3:], z) + cross(w, zd)
        rmp = leaves.axis_attractor(goal[3:6] - z, zd, c.axis_gain, c.axis_damping, c.axis_metric)
        A += Jz.T @ (rmp.metric @ Jz)
        b += Jz.T @ (rmp.metric @ (rmp.accel - z_drift))
        # obstacle leaves, one per pair
        pairs = snap.pairs
        if len(pairs.distance):
            G = pairs.gradient
            dd = G @ qd + pairs.rate
            rmp = leaves.obstacle_avoidance(pairs.distance, dd, *self._obstacle)
            A += G.T @ (rmp.metric[:, None] * G)
            b += G.T @ (rmp.metric * (rmp.accel - pairs.drift))
        # joint limits (x_hi = q_hi - q: J = -I; x_lo = q - q_lo: J = I), diagonal
        hi = leaves.joint_limit(self.q_hi - q, -qd, *self._limit)
        lo = leaves.joint_limit(q - self.q_lo, qd, *self._limit)
        diag = hi.metric + lo.metric
        force = lo.metric * lo.accel - hi.metric * hi.accel
        # default configuration and joint damping (x = q), diagonal
        rest = leaves.posture(q - self.q_rest, qd, c.posture_gain, c.posture_damping,
                              c.posture_limit, c.posture_metric)  # fmt: skip
        damp = leaves.joint_damping(qd, c.damping_gain, c.damping_metric, c.damping_inertia)
        diag = diag + rest.metric + damp.metric
        force = force + rest.metric * rest.accel + damp.metric * damp.accel
        A[np.diag_indices(n)] += diag
        b += force
        try:  # M is positive definite (the damping leaf's inertia): M^+ = M^-1, by Cholesky
            L = np.linalg.cholesky(A)
            qdd = np.linalg.solve(L.T, np.linalg.solve(L, b))
        except np.linalg.LinAlgError:
            qdd = np.linalg.pinv(A, rcond=c.rcond, hermitian=True) @ b
        return Resolved(qdd, A, b)

    # ----------------------------------------------------------------------------- Method
    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: forget the obstacles' last positions."""
        self.sensor.reset()
        self._last = None

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: resolve at the measured state, send the period's motion."""
        require_finite(goal=obs.goal)  # before the sensor's state changes
        snap = self.sensor.measure(obs.t, obs.q, obs.qd, obs.obstacles, obs.obstacle_radii,
                                   self.config.obstacle_radius, drift=True)  # fmt: skip
        out = self.resolve(snap, obs.goal)
        self._last, self._pairs = out, len(snap.pairs.distance)
        dt = self.dt
        q_star = obs.q + (0.5 * dt) * obs.qd + (0.125 * dt * dt) * out.qdd
        qd_star = obs.qd + (0.5 * dt) * out.qdd
        return Command.joint(q_star, qd_star)

    def internals(self) -> dict[str, Any]:
        """The resolved acceleration, the number of obstacle leaves and the metric's condition."""
        if self._last is None:
            return {"qdd": None, "pairs": 0, "metric_cond": float("nan")}
        return {"qdd": self._last.qdd, "pairs": self._pairs,
                "metric_cond": float(np.linalg.cond(self._last.metric))}  # fmt: skip
