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

import numpy as np

from amex.core.types import Command
from amex.methods import Method, MethodConfig, Observation


@dataclass
class ServoConfig(MethodConfig):
    """Servo settings (inner gains inherited: AMEX's velocity-led Kp 1, Kd 100).

    Attributes:
        speed: cruise speed of the TCP [m/s].
        accel: largest speed increase [m/s^2].
        approach_rate: speed per metre of remaining distance near the goal [1/s].
    """

    name: str = "servo"
    speed: float = 0.1
    accel: float = 0.5
    approach_rate: float = 2.0


class Servo(Method):
    """Straight-line servoing to the goal (module notes)."""

    name = "servo"
    config_class = ServoConfig

    def __init__(self, config: ServoConfig, dt: float) -> None:
        if not (config.speed > 0 and config.accel > 0 and config.approach_rate > 0):
            raise ValueError(f"servo: speed, accel, approach_rate must be > 0, got {config}")
        self.config = config
        self.dt = float(dt)
        self._speed = 0.0

    @classmethod
    def from_plan(cls, plan, config, dt, robot=None) -> Servo:
        """See :meth:`amex.methods.Method.from_plan`; the plan is not used."""
        return cls(config, dt)

    def reset(self, obs: Observation) -> None:
        """See :meth:`amex.methods.Method.reset`: start at rest."""
        self._speed = 0.0

    def step(self, obs: Observation) -> Command:
        """See :meth:`amex.methods.Method.step`."""
        c = self.config
        error = obs.goal[:3] - obs.y[:3]
        distance = math.sqrt(float(error @ error))
        self._speed = min(c.speed, self._speed + c.accel * self.dt, c.approach_rate * distance)
        v = error * (self._speed / distance) if distance > 1e-9 else np.zeros(3)
        y = np.concatenate([obs.y[:3] + v * self.dt, obs.goal[3:]])
        return Command(y=y, yd=np.concatenate([v, np.zeros(3)]))

    def internals(self) -> dict:
        """The commanded speed [m/s]."""
        return {"speed": self._speed}
