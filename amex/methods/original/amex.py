"""AMEX as the authors' harness ran it (``pfc.cpp`` and ``spline.cpp`` at commit b475fa1fe).

``implementation=original method=amex`` selects it (``experiment=original`` sets it). It differs
from :class:`~amex.methods.amex.AMEX` (ours) as ``docs/methods/originals.md`` records, and nothing
here is guarded:

* The plan is an order-2 de Boor spline over the N + 1 reference samples, i.e. piecewise linear
  through them at s_k = k / N (the paper says quadratic), read as ``value(s)``; for s >= 1 it is the
  last sample. Its derivative is a central difference over one knot spacing, one-sided at the ends.
* Phase, Eq. 8. The first two updates add Delta s_ref = dt / T_ref (so after the first update s is
  already Delta s_ref); then ``s += Delta s_ref * delta_g * delta_y`` with
  ``delta_g = ||g_ref - tau_ref(s_prev)|| / ||g_prev - y||`` (the goal of the previous update) and
  ``delta_y = ||y - y_prev|| / ||y*_prev - y_prev||``, unclipped.
* Warp, Eq. 7: with ``Delta y = y - tau_plan(s)`` and ``Delta g = g - g_prev``, every sample
  from the last one at or before s on gains
  ``Delta y + (Delta g - Delta y)((s_k - 1) / (1 - s) + 1)``; the samples before it stay.
* Target, Eq. 9: ``y_dot* = d ||tau_ref'(s)|| / T_ref`` with d the unit tangent of the warped plan
  at s, and ``y* = y + dt y_dot*``.
* The goal's axis is the reference's final axis (the harness set the goal object's orientation to
  it), only the position comes from the observation.

A zero goal distance, a zero commanded step or s = 1 divide by zero as in the original; the
episode then ends with ``nan_command``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from amex.core.types import Command, Observation
from amex.methods.amex import AMEXConfig, AMEXTarget, target_internals
from amex.methods.base import Method

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


class PiecewiseLinearPlan:
    """Samples ``points`` (N + 1, m) at s_k = k / N, evaluated as ``spline.cpp`` does."""

    def __init__(self, points: np.ndarray) -> None:
        self.points = np.array(points, dtype=float)
        self.n = len(self.points) - 1
        self.knots = np.arange(self.n + 1) / self.n

    def value(self, s: float) -> np.ndarray:
        """De Boor order 2: linear between the two samples around s; the last one past s = 1."""
        n = self.n
        k = int(math.floor((s + 1e-9) * n))  # the interval de Boor's knot search finds
        if k >= n:
            return self.points[-1].copy()
        k = max(k, 0)
        offset = s - self.knots[k]
        w = 0.0 if offset == 0.0 else offset * n
        return (1.0 - w) * self.points[k] + w * self.points[k + 1]

    def derivative(self, s: float) -> np.ndarray:
        """Finite difference over one knot spacing: central, one-sided at the ends."""
        ds = 1.0 / self.n
        if s + ds > 1.0:
            return (self.value(s) - self.value(s - ds)) / ds
        if s - ds < 0.0:
            return (self.value(s + ds) - self.value(s)) / ds
        return (self.value(s + ds) - self.value(s - ds)) / (2.0 * ds)

    def warp(self, delta_goal: np.ndarray, delta_state: np.ndarray, s: float) -> None:
        """Eq. 7 on the samples from the last one at or before ``s`` on (``Spline::transform``)."""
        first = max(int(np.searchsorted(self.knots, s, side="right")) - 1, 0)
        weight = (self.knots[first:] - 1.0) / (1.0 - s) + 1.0
        self.points[first:] += delta_state + np.outer(weight, delta_goal - delta_state)


class AMEXOriginal(Method):
    """The authors' AMEX (module notes).

    Args:
        plan: the reference; its task path ``plan.y``, N + 1 samples over T_ref, shape (N + 1, m).
        config: :class:`~amex.methods.amex.AMEXConfig`; none of its parameters apply (only the
            inner gains).
        dt: outer period [s].
        robot: not used.
    """

    name = "amex"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = AMEXConfig
    needs_motion = True  # Eq. 8, as in ours

    def __init__(
        self,
        plan: ReferencePlan,
        config: AMEXConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        super().__init__(plan, config, dt, robot)
        Y = np.array(plan.y, dtype=float)
        self.samples = Y
        self.duration = float(plan.duration)
        self.ds_ref = self.dt / self.duration
        self.reference = PiecewiseLinearPlan(Y)
        self.g_ref = Y[-1].copy()
        self.restart()

    def restart(self) -> None:
        """Start a new execution: s = 0, the plan is the reference."""
        self.plan = PiecewiseLinearPlan(self.samples)
        self._s = 0.0
        self._updates = 0
        self._last_goal = self.g_ref.copy()  # g_ref + (x0 - tau_ref(0)) with x0 = tau_ref(0)
        self._state_prev = self.samples[0].copy()
        self._target_prev = self.samples[0].copy()
        self._last: AMEXTarget | None = None

    @property
    def s(self) -> float:
        """The phase."""
        return self._s

    def update(self, y: np.ndarray, g: np.ndarray) -> AMEXTarget:
        """One ``Pfc::iterate`` for the task state y and the goal g (position used), shapes (m,)."""
        goal = self.g_ref.copy()
        goal[:3] = g[:3]
        delta_g: Any = 1.0
        delta_y: Any = 1.0
        norm = np.linalg.norm  # numpy floats: a zero divisor gives inf or nan, as in C++
        if self._updates >= 2:
            remaining = self.g_ref - self.reference.value(self._s)
            delta_g = norm(remaining) / norm(self._last_goal - y)
            delta_y = norm(y - self._state_prev) / norm(self._target_prev - self._state_prev)
        self._s += self.ds_ref * delta_g * delta_y
        self._updates += 1
        s = self._s
        self.plan.warp(goal - self._last_goal, y - self.plan.value(s), s)
        self._last_goal = goal
        tangent = self.plan.derivative(s)
        direction = tangent / norm(tangent)
        speed = norm(self.reference.derivative(s)) / self.duration
        yd_star = direction * speed
        y_star = y + yd_star * self.dt
        self._state_prev = np.array(y, dtype=float)
        self._target_prev = y_star
        self._last = AMEXTarget(y_star, yd_star, s, float(delta_g), float(delta_y))
        return self._last

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`."""
        self.restart()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`."""
        with np.errstate(divide="ignore", invalid="ignore"):
            target = self.update(obs.y, obs.goal)
        return Command.task(target.y_star, target.yd_star)

    def internals(self) -> dict[str, Any]:
        """Phase s and the Eq. 8 factors of the last update (as :class:`AMEX`)."""
        return target_internals(self._last, self._s)
