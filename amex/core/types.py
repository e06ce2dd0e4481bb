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
