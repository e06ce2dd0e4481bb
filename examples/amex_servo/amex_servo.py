"""A method from outside amex: servo the TCP straight at the current goal, ignoring the plan.

The smallest complete example of a plugin method (see the README, "Your own method"). It is also
a useful baseline in its own right: purely reactive, no reference plan, so it shows what the plan
contributes to AMEX, DMP and CR on the same environments.

Each outer step commands, like AMEX's Eq. 9, a target one step ahead along a velocity:
``y* = y + v dt``, ``y_dot* = v``, with ``v`` pointing at the goal. Its speed rises by at most
``accel dt`` per step (no velocity jump at the start), is capped at ``speed`` and slows to
``approach_rate * ||g - y||`` near the goal. The TCP axis target is the goal's axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from amex.core.errors import ConfigError
from amex.core.types import Command, require_finite
from amex.methods import Method, MethodConfig, Observation, ReferencePlan

if TYPE_CHECKING:
    from amex.robot import RobotModel


@dataclass
class ServoConfig(MethodConfig):
    """Servo settings (inner gains inherited: AMEX's velocity-led Kp 1, Kd 100).

    Attributes:
        speed: cruise speed of the TCP [m/s].
        accel: largest speed increase [m/s^2].
        approach_rate: speed per metre of remaining distance near the goal [1/s].
    """

    name: str = "servo"
    speed: float = 0.1  # [m/s]
    accel: float = 0.5  # [m/s^2]
    approach_rate: float = 2.0  # [1/s]

    def validate(self) -> None:
        """Raise :class:`ConfigError` unless the speeds are positive (checked before a run)."""
        for key in ("speed", "accel", "approach_rate"):
            if not getattr(self, key) > 0:
                raise ConfigError.invalid(f"method.{key}", getattr(self, key), "> 0")


class Servo(Method):
    """Straight-line servoing to the goal (module notes).

    Built like every method, ``Servo(plan, config, dt, robot)``; ``Method.__init__`` checks the
    arguments (and runs ``ServoConfig.validate``). The plan and the robot are not used.
    """

    name = "servo"
    config_class = ServoConfig
    config: ServoConfig

    def __init__(
        self,
        plan: ReferencePlan,
        config: ServoConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        self._speed = 0.0

    def reset(self, obs: Observation) -> None:
        """See :meth:`amex.methods.Method.reset`: start at rest."""
        self._speed = 0.0

    def step(self, obs: Observation) -> Command:
        """See :meth:`amex.methods.Method.step`."""
        c = self.config
        require_finite(y=obs.y, goal=obs.goal)  # the contract: raise, and change nothing
        error = obs.goal[:3] - obs.y[:3]
        distance = math.sqrt(float(error @ error))
        self._speed = min(c.speed, self._speed + c.accel * self.dt, c.approach_rate * distance)
        v = error * (self._speed / distance) if distance > 1e-9 else np.zeros(3)
        y = np.concatenate([obs.y[:3] + v * self.dt, obs.goal[3:]])
        return Command(y=y, yd=np.concatenate([v, np.zeros(3)]))

    def internals(self) -> dict:
        """The commanded speed [m/s]."""
        return {"speed": self._speed}
