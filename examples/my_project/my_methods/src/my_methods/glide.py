"""Glide: follow the reference plan's timing, its path bent towards the current goal.

At phase ``s = t / T_ref`` the target is ``tau_ref(s) + s (g - g_ref)`` (the reference's shape
moved by the goal's offset as the motion progresses, a linear blend), with its time derivative as
the velocity target; after ``T_ref`` it approaches the goal directly. A simple method of one's
own, to compare against AMEX on identical scenes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from amex.core.errors import ConfigError
from amex.core.types import PD, Command, require_finite
from amex.methods import Method, MethodConfig, Observation


@dataclass
class GlideConfig(MethodConfig):
    """Glide's settings (the inner gains are AMEX's: velocity-led).

    Attributes:
        approach_rate: speed per metre of remaining distance after T_ref [1/s].
    """

    name: str = "glide"
    pos: PD = field(default_factory=lambda: PD(1.0, 100.0, 1.0))
    dir: PD = field(default_factory=lambda: PD(1.0, 100.0, 0.5))
    approach_rate: float = 2.0  # [1/s]

    def validate(self) -> None:
        """Raise :class:`ConfigError` unless the approach rate is positive."""
        if not self.approach_rate > 0:
            raise ConfigError.invalid("method.approach_rate", self.approach_rate, "> 0 [1/s]")


class Glide(Method):
    """The reference, bent towards the goal as it goes (module notes)."""

    name = "glide"
    config_class = GlideConfig
    config: GlideConfig

    def reset(self, obs: Observation) -> None:
        """Nothing to forget: the command depends on the time and the goal only."""

    def step(self, obs: Observation) -> Command:
        """The bent reference at the next outer step's time (module notes)."""
        require_finite(goal=obs.goal, y=obs.y)
        plan = self.reference_plan
        y_ref, T = plan.y, plan.duration
        s = min((obs.t + self.dt) / T, 1.0)
        u = s * (len(y_ref) - 1)
        i = min(int(u), len(y_ref) - 2)
        a = u - i
        offset = obs.goal - y_ref[-1]
        target = (1 - a) * y_ref[i] + a * y_ref[i + 1] + s * offset
        if s < 1.0:
            velocity = (y_ref[i + 1] - y_ref[i]) / plan.dt + offset / T
        else:
            velocity = self.config.approach_rate * (obs.goal - obs.y)
        return Command(y=np.asarray(target, dtype=float), yd=np.asarray(velocity, dtype=float))
