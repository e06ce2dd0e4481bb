"""QP differential IK to the goal with control-barrier constraints (``cbf_ik``).

Each outer step the nominal TCP velocity is greedy proportional tracking of the current goal,
``v_p = gain (g - p)`` capped at ``max_speed``, and ``v_z = axis_gain (z_g - z)`` for the axis;
the barrier filter (:mod:`amex.methods.barrier`: the QP over joint velocities with one
control-barrier constraint per arm-capsule/obstacle pair and the joint-limit barriers, Ames et
al. 2019; Faverjon & Tournassoud 1987) turns it into the joint velocity ``u``. The command is that
velocity held over the outer period ``dt``, sent as CR's joint targets are (the middle of the
period and the velocity over it): ``q* = q + u dt / 2``, ``q_dot* = u``, tracked by the inner
controller's joint task. No reference plan is followed: ``cbf_ik`` is what a greedy reactive
controller with hard safety constraints does (``docs/methods/cbf_ik.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from amex.core.scaling import scaled
from amex.core.types import Command, Observation
from amex.methods.barrier import BarrierConfig, BarrierFilter
from amex.methods.base import Method, MethodConfig, invalid

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


@dataclass
class CBFIKConfig(BarrierConfig, MethodConfig):
    """Greedy goal tracking through the barrier filter (:class:`BarrierConfig`'s settings too).

    Attributes:
        pos: unused (joint targets, tracked with ``controller.joint``).
        dir: unused.
        gain: proportional gain of the TCP velocity towards the goal [1/s].
        max_speed: cap of the nominal TCP speed [m/s] (original units).
        axis_gain: proportional gain of the axis rate towards the goal axis [1/s].
    """

    name: str = "cbf_ik"
    gain: float = 2.0  # [1/s]
    max_speed: float = field(default=1.25, metadata=scaled(1))  # [m/s] (Panda: 0.25)
    axis_gain: float = 2.0  # [1/s]

    def validate(self) -> None:
        """Raise :class:`ConfigError` for settings cbf_ik cannot run with."""
        BarrierConfig.validate(self)
        for key in ("gain", "max_speed"):
            if not getattr(self, key) > 0.0:
                raise invalid(key, getattr(self, key), "> 0")


def goal_velocity(p: np.ndarray, z: np.ndarray, goal: np.ndarray, gain: float, max_speed: float,
                  axis_gain: float) -> np.ndarray:  # fmt: skip
    """The nominal task velocity ``(v_p, v_z)`` of the module notes, shape (6,)."""
    v = np.empty(6)
    v[:3] = gain * (goal[:3] - p)
    speed = math.sqrt(float(v[:3] @ v[:3]))
    if speed > max_speed:
        v[:3] *= max_speed / speed
    v[3:] = axis_gain * (goal[3:6] - z)
    return v


def joint_command(q: np.ndarray, u: np.ndarray, dt: float) -> Command:
    """Joint velocity ``u`` held over ``dt`` as CR's joint targets: ``q + u dt / 2``, ``u``."""
    return Command.joint(q + (0.5 * dt) * u, u.copy())


class CBFIK(Method):
    """QP differential IK with barriers (see the module notes).

    Args:
        plan: the reference plan (not followed; checked like every method's).
        config: :class:`CBFIKConfig` (None: the defaults).
        dt: outer (control) period [s].
        robot: the arm; required.
    """

    name = "cbf_ik"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = CBFIKConfig
    needs_robot = True
    config: CBFIKConfig
    robot: RobotModel

    def __init__(
        self,
        plan: ReferencePlan,
        config: CBFIKConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        self.barrier = BarrierFilter(self.robot, self.config)

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: forget the obstacles' last positions."""
        self.barrier.reset()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: nominal goal velocity, filtered, as joint targets."""
        c = self.config
        snap = self.barrier.measure(obs.t, obs.q, obs.qd, obs.obstacles, obs.obstacle_radii)
        state = snap.state
        v = goal_velocity(state.tcp_pos, state.tcp_axis, obs.goal, c.gain, c.max_speed,
                          c.axis_gain)  # fmt: skip
        u = self.barrier.filter(snap, v).qd
        return joint_command(obs.q, u, self.dt)

    def internals(self) -> dict[str, Any]:
        """The filtered joint velocity, active barrier rows and the slack of the last step."""
        return barrier_internals(self.barrier.last)


def barrier_internals(last: Any) -> dict[str, Any]:
    """The log record of a barrier solution (None before the first step)."""
    if last is None:
        return {"qd_safe": None, "active": 0, "slack": 0.0}
    return {"qd_safe": last.qd, "active": last.active, "slack": last.slack}
