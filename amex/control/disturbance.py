"""Compensation of the torque the controller's model does not explain (``controller.disturbance``).

On a robot that differs from the model (``mismatch.*``) the dynamics are
``M q_ddot + h = tau + tau_d``. Two compensations wrap
:meth:`~amex.control.osc.OperationalSpaceController.torque` for every method: ``observer``, the
generalized-momentum observer of De Luca et al. (``r_dot = K_O (tau_d - r)``, applied as
``tau = clip(M q_ddot* + h - r)``), and ``integral``, integral action on the task errors of the
paper's Eq. 6 (``y_ddot* += K_I z``, with anti-windup). ``none`` (the default) is the paper's
controller, bit for bit. Derivation, discretisation and measurements: ``docs/disturbance.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from amex.control.osc import OperationalSpaceController
from amex.control.state import RobotState
from amex.core.compiled import kernel
from amex.core.errors import ConfigError
from amex.core.types import Command

DISTURBANCE_KINDS = ("none", "observer", "integral")


@dataclass(frozen=True)
class DisturbanceConfig:
    """How the inner controller compensates unmodelled torques.

    Attributes:
        kind: ``none`` (the paper's controller), ``observer`` or ``integral``.
        bandwidth: observer gain K_O, the bandwidth of the estimate [1/s] (rad/s); 20 is a time
            constant of 50 ms, one outer period of ``pr2_like``. Under ``pr2_like`` (10
            environments per task and method) 5-500 were all stable and equally successful;
            10-20 gave the smoothest motions (README).
        limit: the observer's estimate is clamped to this fraction of the torque limits [-].
        integral_gain: K_I of the integral action [1/s] (5-20 measured; 10 in between).
        integral_limit: bound on the integral's task acceleration ``|K_I z|`` [m/s^2, rad/s^2];
            5 was too tight for ``pr2_like`` (CR stalled 1.3 cm short).
    """

    kind: str = "none"
    bandwidth: float = 20.0
    limit: float = 1.0
    integral_gain: float = 10.0
    integral_limit: float = 50.0

    def validate(self) -> None:
        """Raise :class:`ConfigError` for an unknown kind or non-positive gains and limits."""
        if self.kind not in DISTURBANCE_KINDS:
            raise ConfigError.invalid("controller.disturbance", self.kind, DISTURBANCE_KINDS)
        for key, valid in (
            ("bandwidth", "a rate > 0 [1/s]"),
            ("limit", "a fraction of the torque limits in (0, 1]"),
            ("integral_gain", "a rate > 0 [1/s]"),
            ("integral_limit", "a bound > 0 [m/s^2]"),
        ):
            value = getattr(self, key)
            if not (value > 0 and math.isfinite(value)) or (key == "limit" and value > 1):
                raise ConfigError.invalid(f"controller.{_FIELD[key]}", value, valid)


# the RunConfig names of the fields (controller.<name>)
_FIELD = {
    "bandwidth": "observer_bandwidth",
    "limit": "observer_limit",
    "integral_gain": "integral_gain",
    "integral_limit": "integral_limit",
}


class MomentumObserver:
    """Generalized-momentum disturbance observer, discretised per inner step (module docstring).

    Called twice per inner step, :meth:`update` with the measured state, then :meth:`applied`
    with the torque sent to the arm. The arithmetic is one compiled call each
    (:mod:`amex.control.disturbance_kernels`): in numpy its dozen small-array
    operations cost ~30 us a step, the Pinocchio terms (M, C, g) ~4 us.

    Args:
        robot_model: the controller's Pinocchio model.
        dt: inner step [s].
        bandwidth: K_O [1/s].
        bound: clamp of the estimate, shape (n,) [N m].

    Attributes:
        r: the current estimate of ``tau_d``, shape (n,) [N m].
    """

    def __init__(self, robot_model: pin.Model, dt: float, bandwidth: float, bound: np.ndarray):
        n = robot_model.nv
        self.model = robot_model
        self.data = robot_model.createData()
        self.dt = dt
        self.a = math.exp(-bandwidth * dt)
        self.bound = np.asarray(bound, dtype=float)
        self.r = np.zeros(n)
        self._started = False
        self._p_prev = np.zeros(n)  # momentum M q_dot at the previous step [N m s]
        self._beta = np.zeros(n)  # C^T q_dot - g at the current step [N m]
        self._flow_prev = np.zeros(n)  # tau + C^T q_dot - g of the previous step [N m]

    def update(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Advance to the state ``(q, v)`` at the end of the step; return ``r`` [N m]."""
        model, data = self.model, self.data
        M = pin.crba(model, data, q)  # upper triangle read only (valid in every convention)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        g = pin.computeGeneralizedGravity(model, data, q)
        kernel("amex.control.disturbance_kernels", "observer_update")(
            M, C, g, v, self._started, self.a, 1.0 / self.dt, self.bound,
            self.r, self._p_prev, self._flow_prev, self._beta,
        )  # fmt: skip
        self._started = True
        return self.r

    def applied(self, tau: np.ndarray) -> None:
        """Record the torque applied during the coming step (after any clip) [N m]."""
        np.add(tau, self._beta, out=self._flow_prev)


class ObserverController:
    """The OSC with the momentum observer's estimate subtracted: ``tau = clip(tau_osc - r)``."""

    def __init__(self, osc: OperationalSpaceController, dt: float, config: DisturbanceConfig):
        robot = osc.robot
        self.osc = osc
        self.observer = MomentumObserver(
            robot.model, dt, config.bandwidth, config.limit * robot.torque_limit
        )
        self._lo, self._hi = -robot.torque_limit, robot.torque_limit

    def torque(self, state: RobotState, command: Command) -> np.ndarray:
        """Compensated, clipped torques for ``command`` at ``state``, shape (n,) [N m].

        ``M q_ddot* + h`` as in :meth:`OperationalSpaceController.torque` (Pinocchio's RNEA),
        minus the estimate, then clipped once: the observer records the torque actually applied.
        """
        r = self.observer.update(state.q, state.v)
        qdd = self.osc.accelerations(state, command)
        tau = pin.rnea(self.osc.robot.model, state.data, state.q, state.v, qdd)
        compensate = kernel("amex.control.disturbance_kernels", "compensate_and_clip")
        compensate(tau, r, self._lo, self._hi)
        self.observer.applied(tau)
        return tau


class IntegralController:
    """The OSC with integral action on the task errors of Eq. 6 (module docstring)."""

    def __init__(self, osc: OperationalSpaceController, dt: float, config: DisturbanceConfig):
        g = osc.gains
        self.osc = osc
        self.dt = dt
        self.ki = config.integral_gain
        self.bound = config.integral_limit
        self._kd_task = np.r_[np.full(3, g.pos.kd), np.full(3, g.dir.kd)]
        self._kp_task = np.r_[np.full(3, g.pos.kp), np.full(3, g.dir.kp)]
        self.z_task = np.zeros(6)
        self.z_joint = np.zeros(osc.robot.nv)
        self._hi = osc.robot.torque_limit
        self._saturated = False

    def torque(self, state: RobotState, command: Command) -> np.ndarray:
        """Torques with the integral's shifted velocity targets, shape (n,) [N m]."""
        g = self.osc.gains
        y, yd, q, qd = command
        if y is not None:
            yd0 = yd if yd is not None else np.zeros(6)
            if not self._saturated:
                e = self._kp_task * (y - state.y) + self._kd_task * (yd0 - state.yd)
                self.z_task += self.dt * e
            a = np.clip(self.ki * self.z_task, -self.bound, self.bound)
            self.z_task = a / self.ki
            yd = yd0 + a / np.maximum(self._kd_task, 1e-9)
        if q is not None:
            qd0 = qd if qd is not None else np.zeros_like(q)
            if not self._saturated:
                e = g.joint.kp * (q - state.q) + g.joint.kd * (qd0 - state.v)
                self.z_joint += self.dt * e
            a = np.clip(self.ki * self.z_joint, -self.bound, self.bound)
            self.z_joint = a / self.ki
            qd = qd0 + a / max(g.joint.kd, 1e-9)
        tau = self.osc.torque(state, Command(y, yd, q, qd))
        self._saturated = bool(np.any(np.abs(tau) >= self._hi))
        return tau


InnerController = OperationalSpaceController | ObserverController | IntegralController


def make_inner_controller(
    osc: OperationalSpaceController, dt: float, config: DisturbanceConfig | None
) -> InnerController:
    """``osc`` itself for ``kind="none"`` (the paper's controller, bit for bit), else a wrapper."""
    if config is None or config.kind == "none":
        return osc
    config.validate()
    if config.kind == "observer":
        return ObserverController(osc, dt, config)
    return IntegralController(osc, dt, config)
