"""RMPflow's leaf policies (Cheng et al., WAFR 2018, Sec. 4 and App. D; Ratliff et al. 2018).

Each leaf is a Riemannian motion policy in canonical form ``(M, a)`` on its task space ``x``: a
metric ``M(x, x_dot)`` (how much the leaf matters, per direction) and a desired acceleration
``a(x, x_dot)``. Their shapes follow the hand-designed Franka policy of rmp2 (Li et al. 2021,
``rmp2/rmpgraph/rmps/rmps.py``), read for facts; lengths are in the scene's units (the config
converts them, :mod:`amex.core.scaling`). All are pure functions of their inputs.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class RMP(NamedTuple):
    """A leaf RMP in canonical form.

    Attributes:
        metric: ``M``, shape (m, m) (or (k,) for k independent 1-D leaves).
        accel: ``a``, shape (m,) (or (k,)).
    """

    metric: np.ndarray
    accel: np.ndarray


def sigmoid(z: np.ndarray) -> np.ndarray:
    """The logistic function ``1 / (1 + exp(-z))``, without overflow."""
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(z, dtype=float)))


def goal_attractor(
    delta: np.ndarray,
    xd: np.ndarray,
    gain: float,
    damping: float,
    softness: float,
    metric_max: float,
    metric_min: float,
    metric_length: float,
    metric_alpha: float,
    boost: float,
    boost_length: float,
) -> RMP:
    """Goal attractor on the TCP position (Cheng et al. App. D.3), ``delta = g - x`` [m].

    ``a = gain delta / (|delta| + softness) - damping x_dot``: a pull of at most ``gain``
    [m/s^2], linear within ``softness`` of the goal. ``M = b (alpha metric_max I +
    (1 - alpha) metric_min s s^T)`` with ``s = delta / |delta|``, ``alpha = (1 - metric_alpha)
    exp(-|delta|^2 / 2 metric_length^2) + metric_alpha`` (far away the metric acts mostly along
    the way to the goal, leaving the other directions to the obstacles) and the boost
    ``b = 1 + (boost - 1) exp(-|delta|^2 / 2 boost_length^2)`` near the goal.
    """
    dist = math.sqrt(float(delta @ delta))
    accel = gain * delta / (dist + softness) - damping * xd
    s = delta / max(dist, 0.1 * softness, 1e-12)
    alpha = (1.0 - metric_alpha) * math.exp(-0.5 * (dist / metric_length) ** 2) + metric_alpha
    b = 1.0 + (boost - 1.0) * math.exp(-0.5 * (dist / boost_length) ** 2)
    metric = b * (alpha * metric_max * np.eye(3) + (1.0 - alpha) * metric_min * np.outer(s, s))
    return RMP(metric, accel)


def axis_attractor(error: np.ndarray, zd: np.ndarray, gain: float, damping: float,
                   metric: float) -> RMP:  # fmt: skip
    """TCP axis attractor, ``error = z_goal - z``: ``a = gain error - damping z_dot``, M = w I."""
    return RMP(metric * np.eye(3), gain * error - damping * zd)


def obstacle_avoidance(
    d: np.ndarray,
    dd: np.ndarray,
    margin: float,
    gain: float,
    gain_length: float,
    damping: float,
    damping_length: float,
    damping_eps: float,
    velocity_gate: float,
    radius: float,
    metric: float,
    metric_length: float,
    metric_eps: float,
) -> RMP:
    """Obstacle avoidance on each pair's distance (Cheng et al. App. D.2), k 1-D leaves.

    With ``x = max(d - margin, 0)`` and the approach gate ``u = 1 - sigmoid(d_dot /
    velocity_gate)`` (near 1 approaching, near 0 leaving): ``a = gain exp(-x / gain_length) -
    u damping d_dot / (x / damping_length + damping_eps)`` (repulsion, and braking of the
    approach) and ``M = u metric (1 - x / radius)^2 / (x / metric_length + metric_eps)`` for
    ``x < radius``, 0 beyond (a barrier-like weight that vanishes smoothly at ``radius``).
    """
    x = np.maximum(d - margin, 0.0)
    gate = 1.0 - sigmoid(dd / velocity_gate)
    accel = gain * np.exp(-x / gain_length) - gate * damping * dd / (x / damping_length
                                                                      + damping_eps)
    w = metric / (x / metric_length + metric_eps) * np.square(1.0 - x / radius)
    return RMP(np.where(x < radius, gate * w, 0.0), accel)


def joint_limit(
    x: np.ndarray,
    xd: np.ndarray,
    metric: float,
    metric_length: float,
    metric_eps: float,
    velocity_gate: float,
    damping: float,
    gain: float,
    gain_length: float,
    gain_eps: float,
) -> RMP:
    """Joint-limit avoidance on each joint's distance to each limit (Cheng et al. App. D.4).

    ``x`` [rad]: the distances to the buffered limits, one 1-D leaf each. ``M = (1 -
    sigmoid(x_dot / velocity_gate)) metric / (x / metric_length + metric_eps)``, ``a = gain /
    ((x / gain_length)^2 + gain_eps) - damping x_dot``.
    """
    x = np.maximum(x, 0.0)
    gate = 1.0 - sigmoid(xd / velocity_gate)
    w = gate * metric / (x / metric_length + metric_eps)
    accel = gain / (np.square(x / gain_length) + gain_eps) - damping * xd
    return RMP(w, accel)


def posture(e: np.ndarray, qd: np.ndarray, gain: float, damping: float, limit: float,
            metric: float) -> RMP:  # fmt: skip
    """Default-configuration leaf, ``e = q - q_rest``: a weak PD pull, its pull capped at ``limit``.

    ``a = -gain e' - damping q_dot`` with ``e' = e`` for ``|e| < limit``, else
    ``limit e / |e|``; ``M = metric I`` (a diagonal, returned as its entries).
    """
    norm = math.sqrt(float(e @ e))
    pull = e if norm < limit else e * (limit / norm)
    return RMP(np.full(len(e), metric), -gain * pull - damping * qd)


def joint_damping(qd: np.ndarray, gain: float, metric: float, inertia: float) -> RMP:
    """Joint-velocity damping: ``a = -gain |q_dot| q_dot``, ``M = (metric |q_dot| + inertia) I``."""
    speed = math.sqrt(float(qd @ qd))
    return RMP(np.full(len(qd), metric * speed + inertia), -gain * speed * qd)
