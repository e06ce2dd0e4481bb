"""The small value types shared by methods and the controller (numpy only, no simulator).

Kept apart from :mod:`amex.control` so that :mod:`amex.methods` imports without Pinocchio, coal
or MuJoCo: a method can drive any robot loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np


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
