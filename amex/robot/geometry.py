"""Small geometry both the controller and the planner use: cross products and the joint metric."""

from __future__ import annotations

import math

import numpy as np

from amex.core.errors import ConfigError

#: The joint metrics :func:`joint_metric` knows.
METRICS = ("identity", "original")


def skew(w: np.ndarray) -> np.ndarray:
    """Cross-product matrix: ``skew(w) @ x == w x x``, shape (3, 3).

    Scalar work is done on Python floats (``tolist``): indexing numpy arrays element by element
    costs ~0.1 us per access, which matters at 1 kHz.
    """
    x, y, z = w.tolist()
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` for 3-vectors, without ``np.cross``'s ~20 us of overhead."""
    ax, ay, az = a.tolist()
    bx, by, bz = b.tolist()
    return np.array([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])


def joint_metric(kind: str, n: int) -> tuple[float, ...]:
    """The joint metric diag(H) named ``kind`` for an ``n``-joint arm (empty: the identity).

    ``original``: H = diag(sqrt(n), sqrt(n - 1), ..., 1), the default metric of the authors'
    framework (for their 7-joint chain diag(sqrt 7, sqrt 6, sqrt 5, 2, sqrt 3, sqrt 2, 1)):
    accelerating a joint near the base costs more, roughly as it moves more of the arm.
    """
    if kind == "identity":
        return ()
    if kind == "original":
        return tuple(math.sqrt(n - j) for j in range(n))
    raise ConfigError.invalid("metric", kind, METRICS)
