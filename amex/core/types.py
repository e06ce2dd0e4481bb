"""The small value types shared by methods, the controller and the loop (numpy only).

Kept apart from :mod:`amex.control` so that :mod:`amex.methods` imports without Pinocchio, coal
or MuJoCo: a method can drive any robot loop. A method reads an :class:`Observation` and answers
with a :class:`Command`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from amex.core.errors import InputError


@dataclass
class PD:
    """Gains and weight of one task row of Eq. 5-6.

    Attributes:
        kp: stiffness [1/s^2].
        kd: damping [1/s].
        weight: the cost weight ``c`` of Eq. 5 (dimensionless, relative to the others).
    """

    kp: float
    kd: float
    weight: float


class Command(NamedTuple):
    """What the outer loop sends to the inner controller (held for one outer period).

    Either a task-space target ``y, yd`` (6-D: TCP position [m] and z-axis; velocities per second),
    or a joint-space target ``q, qd`` [rad, rad/s], or both.
    """

    y: np.ndarray | None = None
    yd: np.ndarray | None = None
    q: np.ndarray | None = None
    qd: np.ndarray | None = None

    @classmethod
    def task(cls, y: np.ndarray, yd: np.ndarray) -> Command:
        """``Command(y=y, yd=yd)``, made without NamedTuple's keyword path (~0.5 us per step)."""
        return tuple.__new__(cls, (y, yd, None, None))

    @classmethod
    def joint(cls, q: np.ndarray, qd: np.ndarray) -> Command:
        """``Command(q=q, qd=qd)``, made as :meth:`task`."""
        return tuple.__new__(cls, (None, None, q, qd))


def require_finite(**values: Any) -> None:
    """Raise :class:`InputError` naming the first argument that holds a NaN or an infinity.

    Fast for the small vectors of an outer step (one dot product each); call it before any state
    changes, so that a rejected input leaves the caller as it was.
    """
    for name, value in values.items():
        a = np.ravel(value)
        if not math.isfinite(float(a @ a)) and not np.isfinite(a).all():  # (huge values pass)
            raise InputError(f"non-finite {name}: {np.array2string(a, threshold=8)}")


@dataclass(frozen=True, slots=True)
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

    @classmethod
    def prechecked(
        cls,
        t: float,
        q: np.ndarray,
        qd: np.ndarray,
        y: np.ndarray,
        yd: np.ndarray,
        goal: np.ndarray,
        obstacles: np.ndarray,
        obstacle_radii: np.ndarray,
    ) -> Observation:
        """The same observation, built without the finiteness check.

        For a caller that has already found every value finite (the episode loop, 100 times a
        second).
        """
        obs = object.__new__(cls)
        put = object.__setattr__
        put(obs, "t", t)
        put(obs, "q", q)
        put(obs, "qd", qd)
        put(obs, "y", y)
        put(obs, "yd", yd)
        put(obs, "goal", goal)
        put(obs, "obstacles", obstacles)
        put(obs, "obstacle_radii", obstacle_radii)
        return obs

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


#: The parts of a :class:`Command` and the dimension each must have: task (6) or joints (n).
_PARTS = (("y", "task"), ("yd", "task"), ("q", "joints"), ("qd", "joints"))


def command_problem(command: object, n_joints: int, n_task: int = 6) -> str:
    """Why ``command`` is no valid :class:`Command` for an ``n_joints`` arm ("" if it is one).

    Valid: a :class:`Command` whose parts are each None or a 1-D float array of the task's size
    (``y``, ``yd``: ``n_task``) or the arm's (``q``, ``qd``: ``n_joints``); a velocity only with its
    position. Finiteness is not checked here (a non-finite command is numerical trouble of the
    episode, not a malformed answer).
    """
    if not isinstance(command, Command):
        return f"{type(command).__name__} instead of a Command(y, yd, q, qd)"
    sizes = {"task": n_task, "joints": n_joints}
    for name, kind in _PARTS:
        part = getattr(command, name)
        if part is None:
            continue
        size = sizes[kind]
        if not isinstance(part, np.ndarray) or part.dtype != np.float64:
            return f"{name} of type {type(part).__name__}; valid: a float64 numpy array ({size},)"
        if part.shape != (size,):
            return f"{name} of shape {part.shape}; valid: shape ({size},)"
    if command.yd is not None and command.y is None or command.qd is not None and command.q is None:
        return "a velocity target without its position target (yd without y, or qd without q)"
    return ""
