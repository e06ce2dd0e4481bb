"""Plain tracking of the reference plan by time, without any adaptation (the baseline)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from amex.core.types import PD, Command, Observation, require_finite
from amex.methods.base import Method, MethodConfig

if TYPE_CHECKING:  # no simulator stack needed to use a method
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


@dataclass
class TrackConfig(MethodConfig):
    """Tracking gains: a stiff, critically damped PD (omega = 20 rad/s) on the timed reference."""

    name: str = "track"
    pos: PD = field(default_factory=lambda: PD(400.0, 40.0, 1.0))
    dir: PD = field(default_factory=lambda: PD(400.0, 40.0, 0.5))


class Track(Method):
    """Send ``y* = tau_ref(t)``, ``y_dot* = tau_ref'(t)``; hold the final sample after T_ref.

    The goal is ignored: this is what executing a plan without adaptation does when the world
    changes, the reason the paper's methods exist.

    Args:
        plan: the reference; its task path ``plan.y``, shape (N + 1, m), ``plan.dt`` apart.
        config: :class:`TrackConfig` (None: the defaults).
        dt: outer period [s] (the reference is read at the observation's time).
        robot: not used.
    """

    name = "track"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = TrackConfig

    def __init__(
        self,
        plan: ReferencePlan,
        config: TrackConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        self.reference = np.asarray(plan.y, dtype=float)
        self.dt_ref = float(plan.dt)
        self.velocity = np.gradient(self.reference, self.dt_ref, axis=0)
        self.velocity[-1] = 0.0
        self._index = 0

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`."""
        self._index = 0

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`; linear interpolation between reference samples."""
        require_finite(t=obs.t)
        u = obs.t / self.dt_ref
        last = len(self.reference) - 1
        k = min(int(u), last - 1)
        a = min(u - k, 1.0)
        self._index = k
        y = (1.0 - a) * self.reference[k] + a * self.reference[k + 1]
        yd = self.velocity[k] if u < last else np.zeros(self.reference.shape[1])
        return Command.task(y, yd)

    def internals(self) -> dict[str, Any]:
        """The reference sample index being tracked."""
        return {"index": self._index}
