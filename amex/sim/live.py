"""Live episodes: a scene moved by hand, and the method's timing and plan as the page shows them.

``amex-live`` (:mod:`amex.app.live`) runs the ordinary two-rate loop
(:func:`amex.sim.episode.run_episode`) with two stand-ins, so that there is one episode loop:

* :class:`LiveScenario` duck-types :class:`~amex.sim.scenario.Scenario`: ``goal_at(t)`` and
  ``obstacles_at(t)`` follow the environment's own closed-form motion until a hand moves them, and
  then return where the hand put them. Every change is stamped with the simulation time it was
  made at, so ``goal_at`` of an earlier time (a perception latency) answers what the goal was then:
  the episode's :class:`~amex.sim.perception.GoalSensor` reads ``goal_at`` as for any scene, and
  noise, latency and prediction apply to a dragged goal as to a moving one.
* the recorder that paces the loop is :class:`amex.sim.pacing.LiveRecorder`.
* :class:`TimedMethod` wraps a method and keeps the duration of its last step;
  :func:`method_plan` reads a method's current plan as TCP positions (CR's knots, AMEX's warped
  plan, the DMP's nominal rollout, Track's remaining reference; a plugin's ``internals()["plan"]``).

"""

from __future__ import annotations

import bisect
import copy
import math
import threading
import time
from typing import Any

import numpy as np

from amex.core.types import Command
from amex.methods.amex import AMEX
from amex.methods.base import Method, Observation
from amex.methods.dmp import DMP
from amex.methods.track import Track
from amex.sim.scenario import Scenario

#: The loop re-reads a goal (obstacle) only while its velocity is non-zero; a hand may move them
#: at any time, so a live scene reports at least this velocity [m/s] (it moves nothing).
MARKER_SPEED = 1e-12
HISTORY = 20_000  # changes kept per object (older ones are forgotten; ~minutes of dragging)


class _Track:
    """Where one object (the goal, an obstacle) was put by hand, by simulation time."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self.positions: list[np.ndarray] = []

    def set(self, t: float, position: np.ndarray) -> None:
        if self.times and t < self.times[-1]:
            t = self.times[-1]  # never rewrite the past
        self.positions.append(position)
        self.times.append(t)
        if len(self.times) > HISTORY:
            del self.times[: HISTORY // 2], self.positions[: HISTORY // 2]

    def at(self, t: float) -> np.ndarray | None:
        """The position set last at or before ``t`` (None: not moved by hand by then)."""
        times = self.times
        if not times:
            return None
        if t >= times[-1]:
            return self.positions[-1]
        i = bisect.bisect_right(times, t) - 1
        return self.positions[i] if i >= 0 else None


class LiveScenario:
    """A :class:`Scenario` whose goal and obstacles a hand may move (see the module notes).

    Args:
        base: the environment: its motion applies until a hand moves an object.

    Attributes:
        now: the simulation time of the last outer step [s] (set by the recorder; a change made
            by hand is stamped with it).
    """

    def __init__(self, base: Scenario) -> None:
        self.base = base
        self.task, self.env, self.seed = base.task, base.env, base.seed
        self.goal_axis = base.goal_axis
        self.obstacle_radii = base.obstacle_radii
        self.goal_stop_time = math.inf
        self.now = 0.0
        self._lock = threading.Lock()
        self._goal = _Track()
        self._obstacles = [_Track() for _ in range(base.n_obstacles)]

    @property
    def n_obstacles(self) -> int:
        """Number of obstacle spheres (fixed for an episode)."""
        return self.base.n_obstacles

    @property
    def goal_start(self) -> np.ndarray:
        """The goal at t = 0 [m]."""
        return self.goal_at(0.0)

    @property
    def goal_velocity(self) -> np.ndarray:
        """The base's goal velocity, or :data:`MARKER_SPEED` (the goal may move at any time)."""
        v = self.base.goal_velocity
        return v if np.any(v) else np.array([MARKER_SPEED, 0.0, 0.0])

    @property
    def obstacle_start(self) -> np.ndarray:
        """Obstacle centres at t = 0, shape (k, 3) [m]."""
        return self.obstacles_at(0.0)

    @property
    def obstacle_velocity(self) -> np.ndarray:
        """The base's obstacle velocities, at least :data:`MARKER_SPEED` (see goal_velocity)."""
        v = np.array(self.base.obstacle_velocity, dtype=float)
        if len(v) and not np.any(v):
            v[:, 0] = MARKER_SPEED
        return v

    @property
    def goal_moved_at(self) -> float | None:
        """The simulation time of the last change of the goal by hand [s] (None: never)."""
        times = self._goal.times
        return times[-1] if times else None

    @property
    def moved_by_hand(self) -> bool:
        """Whether a hand moved anything yet."""
        return bool(self._goal.times) or any(o.times for o in self._obstacles)

    def goal_at(self, t: float) -> np.ndarray:
        """Goal position at time ``t`` [s], shape (3,) [m]."""
        with self._lock:
            moved = self._goal.at(t)
        return self.base.goal_at(t) if moved is None else moved

    def obstacles_at(self, t: float) -> np.ndarray:
        """Obstacle centres at time ``t`` [s], shape (k, 3) [m]."""
        if not self._obstacles:
            return self.base.obstacles_at(t)
        centres = self.base.obstacles_at(t)
        with self._lock:
            moved = [o.at(t) for o in self._obstacles]
        if all(m is None for m in moved):
            return centres
        centres = centres.copy()
        for k, m in enumerate(moved):
            if m is not None:
                centres[k] = m
        return centres

    def set_goal(self, position: Any) -> None:
        """Put the goal at ``position`` (3,) [m] from now on (:attr:`now`)."""
        p = _point(position)
        with self._lock:
            self._goal.set(self.now, p)

    def set_obstacle(self, k: int, position: Any) -> None:
        """Put obstacle ``k`` at ``position`` (3,) [m] from now on."""
        p = _point(position)
        with self._lock:
            self._obstacles[k].set(self.now, p)

    def snapshot(self) -> Scenario:
        """A plain :class:`Scenario` of the scene as it is now (for a log's metadata).

        Static where a hand moved something; else the base's own motion.
        """
        base, t = self.base, self.now
        goal_moved = bool(self._goal.times)
        obstacles_moved = any(o.times for o in self._obstacles)
        return Scenario(
            task=base.task,
            env=base.env,
            seed=base.seed,
            goal_start=self.goal_at(t) if goal_moved else base.goal_start,
            goal_velocity=np.zeros(3) if goal_moved else base.goal_velocity,
            goal_stop_time=base.goal_stop_time,
            goal_axis=base.goal_axis,
            obstacle_start=self.obstacles_at(t) if obstacles_moved else base.obstacle_start,
            obstacle_velocity=(
                np.zeros_like(base.obstacle_velocity) if obstacles_moved
                else base.obstacle_velocity
            ),
            obstacle_radii=base.obstacle_radii,
        )  # fmt: skip


def _point(position: Any) -> np.ndarray:
    p = np.array(position, dtype=float).reshape(-1)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise ValueError(f"a position must be 3 finite numbers [m], not {position!r}")
    return p


class TimedMethod(Method):
    """``method`` itself, keeping how long its last :meth:`step` took (:attr:`last_step`) [s]."""

    def __init__(self, method: Method) -> None:
        self.inner = method
        self.name = method.name  # type: ignore[misc]
        self.last_step = math.nan
        self.last_goal: np.ndarray | None = None  # the goal of the last step (a DMP's rollout)

    @classmethod
    def from_plan(
        cls, plan: Any, config: Any = None, dt: float = 0.01, robot: Any = None
    ) -> Method:
        """Not a method of its own: wrap one."""
        raise TypeError("TimedMethod wraps a method; build the method, then wrap it")

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`."""
        self.inner.reset(obs)

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`; timed."""
        self.last_goal = obs.goal
        tic = time.perf_counter()
        try:
            return self.inner.step(obs)
        finally:
            self.last_step = time.perf_counter() - tic

    def internals(self) -> dict[str, Any]:
        """See :meth:`Method.internals`."""
        return self.inner.internals()

    @property
    def finished(self) -> bool:
        """See :meth:`Method.finished`."""
        return self.inner.finished


class PlanView:
    """A method's current plan, read in the loop's thread and drawn in another.

    ``points()`` gives TCP positions, shape (k, 3) [m], or None; a DMP's rollout is stepped only
    when asked for (on a copy taken at the step, ~0.3 ms; rolling it out costs ~10 ms).
    """

    def __init__(self, points: np.ndarray | None = None, twin: DMP | None = None,
                 goal: np.ndarray | None = None) -> None:  # fmt: skip
        self._points, self._twin, self._goal = points, twin, goal

    def points(self) -> np.ndarray | None:
        """The plan's TCP positions (computed at the first call)."""
        if self._twin is not None and self._goal is not None:
            self._points = _dmp_rollout(self._twin, self._goal)
            self._twin = None
        return self._points


def method_plan(method: Method, internals: dict[str, Any], points: int = 60) -> PlanView:
    """The method's current plan (:class:`PlanView`), empty if it has none.

    ``internals["plan"]`` where a method gives one (CR's knots, a plugin's); AMEX's warped plan
    ``tau_plan`` from its phase s to 1 (none in the final approach, a straight line to the
    goal); the DMP's nominal rollout from its state towards the goal of its last step; Track's
    remaining reference. Call it in the loop's thread, between steps.
    """
    inner = method.inner if isinstance(method, TimedMethod) else method
    plan = internals.get("plan")
    if isinstance(plan, np.ndarray) and plan.ndim == 2 and plan.shape[1] >= 3 and len(plan):
        return PlanView(np.array(plan[:, :3], dtype=float))
    if isinstance(inner, AMEX):
        if inner.final_approach or internals.get("y_star") is None:
            return PlanView()
        return PlanView(np.asarray(inner.plan(np.linspace(inner.s, 1.0, points)))[:, :3])
    if isinstance(inner, DMP):
        goal = method.last_goal if isinstance(method, TimedMethod) else None
        return PlanView() if goal is None else PlanView(twin=copy.deepcopy(inner), goal=goal)
    if isinstance(inner, Track):
        index = int(internals.get("index", 0))
        return PlanView(np.array(inner.reference[index:, :3]))
    return PlanView()


def _dmp_rollout(twin: DMP, goal: np.ndarray, horizon: float = 3.0) -> np.ndarray:
    """``twin``'s motion from its state at its own pace towards ``goal`` (steps ``twin``)."""
    out = [twin.y[:3]]
    for k in range(int(horizon / twin.dt)):
        target = twin.update(goal, twin.dt)
        if k % 4 == 3:
            out.append(target.y_star[:3].copy())
    return np.array(out)
