"""The interface every motion-adaptation method implements, and the checks they all share.

A method is built from a reference plan, its config, the outer period and (if it needs one) the
robot, always the same way::

    method = Cls(plan, config, dt, robot)   # config: Cls.config_class, None for its defaults

It then sees an :class:`~amex.core.types.Observation` (measured robot state, current goal,
obstacles) at the outer rate and answers with a :class:`~amex.core.types.Command` for the inner
controller. It never touches the simulator, so it can be driven from any robot loop, with plain
numpy arrays (:meth:`~amex.plan.reference.ReferencePlan.from_path` makes a plan from a path).
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass, field, fields
from numbers import Real
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from amex.core.errors import ConfigError
from amex.core.schema import check_tree
from amex.core.types import PD, Command, Observation, require_finite

if TYPE_CHECKING:  # methods stay importable without the simulator stack
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

__all__ = [
    "MIN_REFERENCE_TRAVEL",
    "Method",
    "MethodConfig",
    "Observation",
    "require_finite",
]

#: Smallest start-to-goal distance ``||tau_ref(1) - tau_ref(0)||`` [task units: m] of a reference
#: that :attr:`Method.needs_motion` methods accept. AMEX measures its progress as the
#: reference's remaining distance to its goal (Eq. 8's delta_g); a reference that barely moves
#: lends it no progress, and AMEX stands still wherever the goal is elsewhere. 1 cm is a third of
#: the benchmark's absolute success radius (3 cm), so a reference that moves less does not move
#: at the resolution at which arrival is scored; it lies far above what the planner leaves when
#: the reference goal is the start TCP itself (3e-16 on the Panda, 1.1e-3 on the UR5, whose start
#: axis is 1e-3 off the goal axis) and far below the shortest configured reference (0.24 m,
#: Panda and UR5 at scale 0.2; 1.8 in the original scene).
MIN_REFERENCE_TRAVEL = 0.01
#: Fewest reference samples a method accepts (a quadratic spline needs 3; the planner's minimum).
MIN_SAMPLES = 3


@dataclass
class MethodConfig:
    """Settings every method has: the inner controller's gains for its task-space commands.

    A method's config subclasses this; range checks that do not depend on the plan go in its
    ``validate()`` (run by :func:`amex.core.schema.check_tree` when a run's configuration is
    validated, and by :class:`Method` at construction).

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
        """The method's own parameters and their values."""
        return {name: getattr(self, name) for name in self.param_names()}


def invalid(key: str, value: object, valid: str | Any) -> ConfigError:
    """The :class:`ConfigError` of a method parameter, named as on the command line."""
    return ConfigError.invalid(f"method.{key}", value, valid)


class Method(abc.ABC):
    """A motion-adaptation method: reference plan in, one command per outer step out.

    Subclasses set :attr:`name` (equal to their module name and Hydra option) and
    :attr:`config_class`, call ``super().__init__(plan, config, dt, robot)`` first in their
    constructor (it keeps the checked arguments as :attr:`reference_plan`, :attr:`config`,
    :attr:`dt` and :attr:`robot`) and implement :meth:`reset` and :meth:`step`.

    Args:
        plan: the reference plan tau_ref.
        config: the method's settings, a :attr:`config_class` (another object with all its
            fields is converted); None: its defaults.
        dt: outer (control) period [s], in (0, T_ref].
        robot: the robot model; required by methods with :attr:`needs_robot`.

    Raises:
        ConfigError: the plan's task path is not finite or not (N + 1 >= 3, m), ``dt`` is out
            of range, the config is of another kind or fails its ``validate()``, the robot is
            missing or does not match the plan's joints, or (:attr:`needs_motion`) the
            reference moves less than :data:`MIN_REFERENCE_TRAVEL`.
    """

    name: ClassVar[str] = ""
    config_class: ClassVar[type[MethodConfig]] = MethodConfig
    #: Whether the method needs the robot model and the plan's joint trajectory (e.g. CR).
    needs_robot: ClassVar[bool] = False
    #: Whether the reference must move at least :data:`MIN_REFERENCE_TRAVEL` (e.g. AMEX).
    needs_motion: ClassVar[bool] = False
    #: Whether every step's command and :meth:`internals` are new objects that neither the
    #: method nor anything else changes later: a new dict at each call, its arrays and lists,
    #: the command's arrays and the inputs of its lazy values new or never written in place.
    #: A recorder may then keep them as they are (the log does, without copies: issue #29).
    #: False by default: the steps of a method that reuses its buffers are copied. Every
    #: built-in method says True, and tests/methods/test_fresh_steps.py checks each one.
    fresh_steps: ClassVar[bool] = False

    def __init__(
        self,
        plan: ReferencePlan,
        config: MethodConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        label = type(self).__name__
        y = np.asarray(plan.y)
        if y.ndim != 2 or len(y) < MIN_SAMPLES or not np.isfinite(y).all():
            raise ConfigError(
                f"{label}: invalid reference plan y of shape {y.shape}; valid: finite samples "
                f"of shape (N + 1 >= {MIN_SAMPLES}, m)"
            )
        duration = float(plan.duration)
        if not (math.isfinite(duration) and duration > 0.0):
            raise ConfigError.invalid("plan duration", duration, "> 0 [s]")
        period = float(dt) if isinstance(dt, Real) and not isinstance(dt, bool) else math.nan
        if not 0.0 < period <= duration:  # (False for nan)
            raise ConfigError.invalid("dt", dt, f"in (0, T_ref = {duration:g}] [s]")
        self.config = self._checked_config(config)
        if self.needs_robot:
            if robot is None:
                usage = f"{label}(plan, config, dt, robot)"
                raise ConfigError(f"{label} needs the robot model: {usage}")
            q = np.asarray(plan.q)
            if q.shape != (len(y), robot.nv) or not np.isfinite(q).all():
                shape = f"finite ({len(y)}, {robot.nv}) [rad], a joint row per sample"
                raise ConfigError.invalid("plan q shape", q.shape, shape)
        if self.needs_motion:
            travel = float(np.linalg.norm(y[-1] - y[0]))
            if not travel >= MIN_REFERENCE_TRAVEL:
                raise ConfigError(
                    f"{label}: the reference must move: its start and goal are {travel:.3g} "
                    f"apart; valid: >= {MIN_REFERENCE_TRAVEL:g} [task units: m] (a reference "
                    "goal at the start TCP gives the phase of Eq. 8 no progress to measure)"
                )
        self.reference_plan = plan
        self.dt = period
        self.robot = robot

    @classmethod
    def _checked_config(cls, config: Any) -> Any:
        """``config`` as a :attr:`config_class` instance, checked (see the class notes).

        An instance of the class is used as is; another object with all the class's fields (a
        config of the same fields) is converted; then :func:`~amex.core.schema.check_tree` checks
        it as a run's validation does (finite numbers, the fields' limits, the config's own
        ``validate()``), naming the fields ``method.<field>``.
        """
        want = cls.config_class
        if config is None:
            config = want()
        elif not isinstance(config, want):
            names = [f.name for f in fields(want)]
            missing = [n for n in names if not hasattr(config, n)]
            if missing or isinstance(config, type):
                raise ConfigError(
                    f"invalid {cls.__name__} config {type(config).__name__}; valid: "
                    f"{want.__name__} or an object with all its fields (missing: "
                    f"{', '.join(missing) or 'an instance'})"
                )
            config = want(**{n: getattr(config, n) for n in names})
        check_tree(config, "method.")
        return config

    @classmethod
    def from_plan(
        cls, plan: ReferencePlan, config: Any = None, dt: float = 0.01, robot: Any = None
    ) -> Method:
        """The same as the constructor ``cls(plan, config, dt, robot)`` (for existing callers)."""
        return cls(plan, config, dt, robot)

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
