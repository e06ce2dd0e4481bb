"""The interface every motion-adaptation method implements, and the data it exchanges.

A method sees an :class:`Observation` (measured robot state, current goal, obstacles) at the outer
rate and answers with a :class:`~amex.control.osc.Command` for the inner controller. It never
touches the simulator, so it can be driven from any robot loop, with plain numpy arrays.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from amex.core.errors import InputError
from amex.core.types import PD, Command

if TYPE_CHECKING:  # methods stay importable without the simulator stack
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


def require_finite(**values: Any) -> None:
    """Raise :class:`InputError` naming the first argument that holds a NaN or an infinity.

    Fast for the small vectors of an outer step (one dot product each); call it before any state
    changes, so that a rejected input leaves the caller as it was.
    """
    for name, value in values.items():
        a = np.ravel(value)
        if not math.isfinite(float(a @ a)) and not np.isfinite(a).all():  # (huge values pass)
            raise InputError(f"non-finite {name}: {np.array2string(a, threshold=8)}")


@dataclass(frozen=True)
class Observation:
    """What a method measures at one outer step.

    Attributes:
        t: time since the episode started [s].
        q: joint positions, shape (7,) [rad].
        qd: joint velocities, shape (7,) [rad/s].
        y: task state (TCP position [m], TCP z-axis), shape (6,).
        yd: task velocity, shape (6,).
        goal: current goal g in the same task space, shape (6,).
        obstacles: obstacle centres, shape (k, 3) [m].
        obstacle_radii: obstacle radii, shape (k,) [m].
    """

    t: float
    q: np.ndarray
    qd: np.ndarray
    y: np.ndarray
    yd: np.ndarray
    goal: np.ndarray
    obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    obstacle_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        """Reject non-finite values where they enter: no method ever sees one (InputError)."""
        try:  # one vectorized test (~3 us); the named check below only when it fails
            parts = [self.q, self.qd, self.y, self.yd, self.goal, self.obstacle_radii]
            finite = math.isfinite(self.t) and bool(
                np.isfinite(np.concatenate([*parts, np.ravel(self.obstacles)])).all()
            )
        except (TypeError, ValueError):
            finite = False
        if not finite:
            require_finite(
                t=self.t,
                q=self.q,
                qd=self.qd,
                y=self.y,
                yd=self.yd,
                goal=self.goal,
                obstacles=self.obstacles,
                obstacle_radii=self.obstacle_radii,
            )


@dataclass
class MethodConfig:
    """Settings every method has: the inner controller's gains for its task-space commands.

    Attributes:
        name: the method's registry key.
        pos: gains of the TCP position task (Eq. 6).
        dir: gains of the TCP axis task (Eq. 6).
    """

    name: str = ""
    pos: PD = field(default_factory=lambda: PD(1.0, 100.0, 1.0))
    dir: PD = field(default_factory=lambda: PD(1.0, 100.0, 0.5))

    @classmethod
    def param_names(cls) -> list[str]:
        """The method's own parameters: the fields of ``cls`` that :class:`MethodConfig` lacks."""
        base = {f.name for f in fields(MethodConfig)}
        return [f.name for f in fields(cls) if f.name not in base]

    def params(self) -> dict[str, Any]:
        """The method's own parameters and their values (for a method's constructor)."""
        return {name: getattr(self, name) for name in self.param_names()}


class Method(abc.ABC):
    """A motion-adaptation method: reference plan in, one command per outer step out.

    Subclasses set :attr:`name` (equal to their module name and Hydra option) and
    :attr:`config_class`, and implement :meth:`from_plan`, :meth:`reset` and :meth:`step`.
    """

    name: ClassVar[str] = ""
    config_class: ClassVar[type[MethodConfig]] = MethodConfig

    @classmethod
    @abc.abstractmethod
    def from_plan(
        cls, plan: ReferencePlan, config: MethodConfig, dt: float, robot: RobotModel | None = None
    ) -> Method:
        """Build the method for ``plan`` with outer period ``dt`` [s]."""

    @abc.abstractmethod
    def reset(self, obs: Observation) -> None:
        """Start a new execution from ``obs`` (called once before the first :meth:`step`)."""

    @abc.abstractmethod
    def step(self, obs: Observation) -> Command:
        """One outer-loop update: the next command for the inner controller."""

    def internals(self) -> dict[str, Any]:
        """The method's internal state after the last step, for logs (e.g. AMEX's phase)."""
        return {}

    @property
    def finished(self) -> bool:
        """Whether the method ended the execution at its last step (the episode then stops).

        False for every method but the authors' CR, which stopped at the end of its horizon.
        """
        return False
