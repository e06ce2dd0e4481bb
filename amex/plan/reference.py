"""The reference plan: what every method starts from (the paper's tau_ref, Section IV)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amex.plan.weights import CostWeights


@dataclass(frozen=True)
class ReferencePlan:
    """A joint trajectory planned in the obstacle-free reference scene and its task-space image.

    Sample k is at time ``k * dt``; the plan lasts ``duration = (len(y) - 1) * dt``.

    Attributes:
        q: joint trajectory, shape (N + 1, n) [rad]; ``q[0]`` is the start.
        y: task-space image tau_ref: TCP position [m] and TCP z-axis, shape (N + 1, 6).
        dt: sample period [s].
        metric: the joint metric diag(H) its acceleration cost used (empty: identity); CR
            replans with the same one.
    """

    q: np.ndarray
    y: np.ndarray
    dt: float
    metric: tuple[float, ...] = ()

    @classmethod
    def from_path(cls, y: np.ndarray, duration: float) -> ReferencePlan:
        """A task-space-only plan: the samples ``y`` equally spaced over ``duration`` [s].

        For using a method without the planner (e.g. AMEX on a 2-D path). The joint trajectory
        is empty, shape (N + 1, 0): methods that replan in joint space (CR) refuse it. The
        plan's ``duration`` is ``N * (duration / N)``, which may differ from ``duration`` in the
        last bit.

        Args:
            y: tau_ref samples, shape (N + 1 >= 2, m).
            duration: T_ref [s], > 0.

        Raises:
            ConfigError: ``y`` is not finite of shape (N + 1 >= 2, m), or ``duration`` <= 0.
        """
        import math

        from amex.core.errors import ConfigError

        path = np.array(y, dtype=float)
        if path.ndim != 2 or len(path) < 2 or not np.isfinite(path).all():
            raise ConfigError.invalid("path shape", path.shape, "finite (N + 1 >= 2, m)")
        if not (math.isfinite(duration) and duration > 0.0):
            raise ConfigError.invalid("duration", duration, "> 0 [s]")
        return cls(q=np.zeros((len(path), 0)), y=path, dt=float(duration) / (len(path) - 1))

    @property
    def duration(self) -> float:
        """T_ref [s]."""
        return (len(self.y) - 1) * self.dt

    @property
    def goal(self) -> np.ndarray:
        """g_ref = tau_ref(1), shape (6,)."""
        return self.y[-1]

    @property
    def times(self) -> np.ndarray:
        """Sample times, shape (N + 1,) [s]."""
        return np.arange(len(self.y)) * self.dt


@dataclass
class _PlanHorizon:
    duration: float = 4.0  # [s] T_ref
    dt: float = 0.01  # [s]
    max_iterations: int = 20  # [-] original


@dataclass
class PlanConfig(CostWeights, _PlanHorizon):
    """How the reference plan is computed: 400 steps over 4 s, <= 20 iterations (the original's).

    The cost weights are :class:`~amex.plan.weights.CostWeights`' (no collision term: the
    reference scene has no obstacle). The bases come in this order to keep the fields, and so
    the configuration's keys, in their order: horizon, weights, the rest.

    Attributes:
        duration: T_ref [s].
        dt: knot spacing [s].
        max_iterations: solver iterations (original: 20).
        metric: joint metric of the acceleration term, ``identity`` or ``original`` (the
            authors' H = diag(sqrt(n), ..., 1); :func:`~amex.robot.geometry.joint_metric`).
        final_velocity_space: the final velocity term on the ``joint`` velocities (ours) or on
            the ``tcp`` position's (the original's).
        solver: ``levenberg`` (:func:`~amex.plan.optimizer.solve_trajectory`) or ``newton``
            (the authors' :func:`~amex.plan.optimizer.solve_trajectory_newton`).
    """

    metric: str = "identity"
    final_velocity_space: str = "joint"
    solver: str = "levenberg"

    @property
    def steps(self) -> int:
        """Number of knots after the start, ``duration / dt``."""
        return int(round(self.duration / self.dt))
