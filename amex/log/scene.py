"""The 3-D scene of an episode log: goal, obstacles, reference, executed path and plan.

Four ``foxglove.SceneUpdate`` topics of :class:`~amex.log.writer.EpisodeLogger`'s log:

* ``/scene/world``: the goal (a sphere of the success radius and a dot at its centre) and the
  obstacle spheres, written when they moved by more than 1 mm, else once a second;
* ``/scene/reference``: the reference plan's TCP path, once a second;
* ``/scene/path``: the executed TCP path, a point every ``path_every`` outer steps;
* ``/scene/plan``: the method's current plan (an ``(k, 3)`` array), decimated.

Colours are the palette's (:mod:`amex.core.palette`, through :mod:`amex.log.messages`): the goal
gold, the obstacles black, the reference red, the executed path in the method's colour and its
plan lighter.
"""

from __future__ import annotations

from typing import Any

import foxglove
import numpy as np
from foxglove.channels import SceneUpdateChannel
from foxglove.messages import Point3, SceneEntity, SceneUpdate

from amex.log import messages as M
from amex.log.frames import WORLD_FRAME, sim_stamp

SUCCESS_RADIUS = 0.03  # [m] drawn around the goal (the paper's success radius)


class SceneChannels:
    """The scene topics of one log, and what was last drawn on them.

    Args:
        context: the log's ``foxglove.Context`` (channels are created in it, in topic order).
        reference: the reference plan's TCP points, already decimated.
        obstacle_radii: the obstacles' radii [m], shape (k,).
        obstacles_move: whether the obstacles move (their positions then count as motion).
        method: the method's name (its colour).
        max_line_points: plan lines are decimated to at most this many points.
    """

    def __init__(
        self,
        context: foxglove.Context,
        reference: list[Point3],
        obstacle_radii: np.ndarray,
        *,
        obstacles_move: bool,
        method: str,
        max_line_points: int,
    ) -> None:
        self.world = SceneUpdateChannel("/scene/world", context=context)
        self.path = SceneUpdateChannel("/scene/path", context=context)
        self.plan = SceneUpdateChannel("/scene/plan", context=context)
        self.reference = SceneUpdateChannel("/scene/reference", context=context)
        self._reference = reference
        self._radii = np.asarray(obstacle_radii, dtype=float)
        self._obstacles_move = obstacles_move
        self._path_color, self._plan_color = M.path_color(method), M.plan_color(method)
        self._max_line_points = max_line_points
        self._path_points: list[Point3] = []
        self._world_key: list[float] | None = None
        self._world_time = 0.0
        self.next_reference = 0.0  # [s] when the reference line is due again

    def channels(self) -> list[Any]:
        """The four channels (to close them)."""
        return [self.world, self.path, self.plan, self.reference]

    def publish_world(self, t: float, goal: np.ndarray, obstacles: np.ndarray) -> None:
        """Goal and obstacles: when they moved (> 1 mm) or a second passed since last time."""
        gx, gy, gz = goal[:3].tolist()
        key = [gx, gy, gz]
        if self._obstacles_move:
            key += np.asarray(obstacles, dtype=float).ravel().tolist()
        last = self._world_key
        if last is not None and t < self._world_time + 1.0:
            if len(key) == 3:  # the common case, without a generator
                moved = abs(gx - last[0]) + abs(gy - last[1]) + abs(gz - last[2])
            else:
                moved = sum(abs(a - b) for a, b in zip(key, last, strict=True))
            if moved < 1e-3:
                return
        self._world_key, self._world_time = key, t
        stamp = sim_stamp(t)
        entities = [
            SceneEntity(
                timestamp=stamp,
                frame_id=WORLD_FRAME,
                id="goal",
                spheres=[
                    M.sphere((gx, gy, gz), 2 * SUCCESS_RADIUS, M.GOAL_COLOR),
                    M.sphere((gx, gy, gz), 0.01, M.GOAL_DOT_COLOR),
                ],
            )
        ]
        if len(self._radii):
            spheres = [
                M.sphere(c, 2 * float(r), M.OBSTACLE_COLOR)
                for c, r in zip(np.asarray(obstacles).tolist(), self._radii.tolist(), strict=False)
            ]
            entities.append(
                SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id="obstacles", spheres=spheres)
            )
        self.world.log(SceneUpdate(entities=entities), log_time=round(t * 1e9))

    def publish_reference(self, t: float) -> None:
        """The reference line, due again a second later."""
        update = M.line_update(sim_stamp(t), "reference", self._reference, M.REFERENCE_COLOR, 2.0)
        self.reference.log(update, log_time=round(t * 1e9))
        self.next_reference = t + 1.0

    def add_path_point(self, x: float, y: float, z: float) -> None:
        """One more point of the executed TCP path (drawn at the next :meth:`publish_path`)."""
        self._path_points.append(Point3(x=x, y=y, z=z))

    def publish_path(self, t: float) -> None:
        """The executed TCP path so far (nothing before its first point)."""
        if self._path_points:
            update = M.line_update(
                sim_stamp(t), "tcp_path", self._path_points, self._path_color, 3.0
            )
            self.path.log(update, log_time=round(t * 1e9))

    def publish_plan(self, t: float, plan: Any) -> None:
        """The method's current plan if it is an ``(k, >=3)`` array (else nothing)."""
        if isinstance(plan, np.ndarray) and plan.ndim == 2 and plan.shape[1] >= 3:
            points = M.points(plan, self._max_line_points)
            update = M.line_update(sim_stamp(t), "plan", points, self._plan_color, 3.0)
            self.plan.log(update, log_time=round(t * 1e9))
