"""DMP with phase stopping: the paper's Eq. 2 slowing Eq. 1's phase while the robot lags."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from amex.core.scaling import scaled
from amex.core.types import Command, Observation, require_finite
from amex.methods.dmp import DMP, DMPConfig, DMPTarget

if TYPE_CHECKING:  # no simulator stack needed to use a method
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


@dataclass
class DMPPSConfig(DMPConfig):
    """DMP with phase stopping (the paper's Eq. 2).

    Attributes:
        beta_ps: phase-stopping gain [1/m^2], in original units (:mod:`amex.core.scaling`: it
            carries scale^-2). The phase runs at ``1 / (1 + beta_ps ||y* - y||^2)`` of its
            speed: 40 on the original scene is 1e3 on the Panda's (scale 0.2), where a 1 cm
            tracking error slows it by 9 %, 3 cm halves it, 10 cm divides it by 11, while the
            sub-millimetre lag of free tracking costs < 0.1 %. Axis components enter unscaled
            (on the Panda's scene an axis error of 0.01 counts like 1 cm).
    """

    name: str = "dmp_ps"
    beta_ps: float = field(default=40.0, metadata=scaled(-2))  # [1/m^2] original units


class DMPPhaseStop(DMP):
    """DMP whose phase slows while the robot lags behind: the paper's Eq. 2 factor on Eq. 1.

    ``tau x_dot = -alpha_x x / (1 + beta_ps ||y* - y||^2)``, y the measured task state and y* the
    DMP's desired state (its position at the step start: the last command). The paper writes Eq. 2
    for an increasing phase; this is Eq. 1's decaying phase slowed by the same factor, which is held
    over a step. The transformation system is unchanged.

    Args:
        plan: see :class:`DMP`.
        config: :class:`DMPPSConfig` (None: the defaults, ``beta_ps`` in original units).
        dt: see :class:`DMP`.
        robot: not used.
    """

    name = "dmp_ps"
    config_class = DMPPSConfig
    config: DMPPSConfig

    def __init__(
        self,
        plan: ReferencePlan,
        config: DMPPSConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        self.beta_ps = float(self.config.beta_ps)
        self._err = np.empty(self.n_dims)

    def phase_rate(self, y: np.ndarray) -> float:
        """Eq. 2's factor ``1 / (1 + beta_ps ||y* - y||^2)`` for the measured y, shape (m,).

        Raises:
            InputError: y holds a NaN or an infinity.
        """
        require_finite(y=y)
        e = np.subtract(self._s.head[self._flip][0], y, out=self._err)
        return 1.0 / (1.0 + self.beta_ps * float(e @ e))

    def update(self, goal: np.ndarray, dt: float, y: np.ndarray | None = None) -> DMPTarget:
        """Advance by ``dt`` [s]; the phase slowed by the error to the measured ``y``, if given."""
        return self._advance(goal, dt, 1.0 if y is None else self.phase_rate(y))

    def step(self, obs: Observation) -> Command:
        """See :meth:`DMP.step`; the phase is also slowed by Eq. 2 with the measured ``obs.y``."""
        target = self._advance(obs.goal, self.dt, self.phase_rate(obs.y))
        return Command.task(target.y_star, target.yd_star)
