"""AMEX through the barrier filter (``amex_cbf``): the paper's Algorithm 1, made safe.

Each outer step AMEX (:class:`~amex.methods.amex.AMEX`, the paper's parameters) gives its target
``(y*, y_dot*)``; its velocity ``y_dot*`` (TCP velocity and axis rate, Eq. 9) is the nominal task
velocity of the same barrier filter as ``cbf_ik`` (:mod:`amex.methods.barrier`, one
implementation), and the filtered joint velocity ``u`` is sent as ``cbf_ik`` sends it,
``q* = q + u dt / 2``, ``q_dot* = u``, to the inner controller's joint task. When the filter
slows the arm, AMEX's phase slows with it (Eq. 8's ``delta_y`` measures the progress the last
command made). ``amex_cbf`` against ``cbf_ik`` isolates AMEX's plan adaptation, against ``amex``
the filter and the joint-level execution (``docs/methods/amex_cbf.md``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from amex.core.types import Command, Observation, require_finite
from amex.methods.amex import AMEX, AMEXConfig
from amex.methods.barrier import BarrierConfig, BarrierFilter
from amex.methods.cbf_ik import barrier_internals, joint_command

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


@dataclass
class AMEXCBFConfig(BarrierConfig, AMEXConfig):
    """AMEX's settings (the paper's) and the barrier filter's (:class:`BarrierConfig`).

    Attributes:
        pos: unused (joint targets, tracked with ``controller.joint``).
        dir: unused.
    """

    name: str = "amex_cbf"

    def validate(self) -> None:
        """AMEX's checks and the filter's."""
        AMEXConfig.validate(self)
        BarrierConfig.validate(self)


class AMEXCBF(AMEX):
    """AMEX whose task velocity passes the barrier filter (see the module notes).

    Args:
        plan: the reference (AMEX's task path ``plan.y``).
        config: :class:`AMEXCBFConfig` (None: the defaults).
        dt: outer (control) period [s].
        robot: the arm; required.
    """

    name = "amex_cbf"
    config_class = AMEXCBFConfig
    needs_robot = True
    config: AMEXCBFConfig
    robot: RobotModel

    def __init__(
        self,
        plan: ReferencePlan,
        config: AMEXCBFConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        self.barrier = BarrierFilter(self.robot, self.config)

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: AMEX restarts, the filter forgets the obstacles."""
        super().reset(obs)
        self.barrier.reset()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: AMEX's update, its velocity filtered, as joint targets."""
        require_finite(y=obs.y, goal=obs.goal)  # before the filter's state changes
        snap = self.barrier.measure(obs.t, obs.q, obs.qd, obs.obstacles, obs.obstacle_radii)
        target = self.update(obs.y, obs.goal)
        u = self.barrier.filter(snap, target.yd_star).qd
        return joint_command(obs.q, u, self.dt)

    def internals(self) -> dict[str, Any]:
        """AMEX's phase and targets, and the filter's last solution."""
        return {**super().internals(), **barrier_internals(self.barrier.last)}
