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

The messages are encoded by :mod:`amex.log.scene_wire` (the SDK's bytes without its objects);
:func:`amex.log.messages.line_update` and :func:`amex.log.messages.sphere` build the same
messages as SDK objects (the tests' oracle).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any, NamedTuple

import foxglove
import numpy as np
from foxglove.messages import SceneEntity, SceneUpdate

from amex.core.lazy import Lazy, LazyRows
from amex.log import messages as M
from amex.log import scene_wire as W
from amex.log.frames import WORLD_FRAME
from amex.log.wire import protobuf_channel

SUCCESS_RADIUS = 0.03  # [m] drawn around the goal (the paper's success radius)


class SceneChannels:
    """The scene topics of one log, and what was last drawn on them.

    Args:
        context: the log's ``foxglove.Context`` (channels are created in it, in topic order).
        reference: the reference plan's TCP points, already decimated, shape (k, 3) [m].
        obstacle_radii: the obstacles' radii [m], shape (k,).
        obstacles_move: whether the obstacles move (their positions then count as motion).
        method: the method's name (its colour).
        max_line_points: plan lines are decimated to at most this many points.
    """

    def __init__(
        self,
        context: foxglove.Context,
        reference: np.ndarray,
        obstacle_radii: np.ndarray,
        *,
        obstacles_move: bool,
        method: str,
        max_line_points: int,
    ) -> None:
        self.world = _scene_channel("/scene/world", context)
        self.path = _scene_channel("/scene/path", context)
        self.plan = _scene_channel("/scene/plan", context)
        self.reference = _scene_channel("/scene/reference", context)
        self._reference_points = W.line_points(reference)  # constant: encoded once
        self._radii = np.asarray(obstacle_radii, dtype=float)
        look = _look(method, tuple(self._radii.tolist()))  # the same for a run's every log
        self._reference_line, self._path_line, self._plan_line = look.lines
        self._obstacles_move = obstacles_move
        self._max_line_points = max_line_points
        self._plan_rows: dict[int, np.ndarray | None] = {}  # plan length -> the rows drawn
        self._path_points = bytearray()  # the executed path's points, encoded as they come
        self._world_key: np.ndarray | None = None  # what counted as motion when last drawn
        self._since = np.array([np.nan])  # [s] when last drawn (NaN: never)
        self._world_layouts = look.world_layouts
        self.next_reference = 0.0  # [s] when the reference line is due again

    def channels(self) -> list[Any]:
        """The four channels (to close them)."""
        return [self.world, self.path, self.plan, self.reference]

    def publish_world(self, t: float, goal: np.ndarray, obstacles: np.ndarray) -> None:
        """Log :meth:`world_updates` of this one step, if due."""
        ns = round(t * 1e9)
        for update in self.world_updates([t], [ns], [goal], [obstacles]).values():
            self.world.base.log(update, ns)

    def world_updates(
        self,
        times: Sequence[float],
        stamps: Sequence[int] | np.ndarray,
        goals: Sequence[np.ndarray] | np.ndarray,
        obstacles: Sequence[np.ndarray],
    ) -> dict[int, bytes]:
        """Goal and obstacles of steps in turn: when they moved (> 1 mm) or a second passed.

        Whether a step is due and its message are computed for all the steps in two compiled
        calls (:func:`amex.log.scene_wire.due_rows`, :func:`~amex.log.scene_wire.encode_spheres`):
        a moving goal or obstacle draws at most every step, and one update built in Python
        cost ~28 us (issue #29).

        Args:
            times: the steps' times [s].
            stamps: the same [ns].
            goals: the goal positions (the first three values of each) [m].
            obstacles: the obstacles' centres at each step, shape (n, 3) each [m].

        Returns:
            The ``/scene/world`` message of each step due, by its index.
        """
        k = len(times)
        goal = np.asarray(goals, dtype=float).reshape(k, -1)[:, :3]
        if self._obstacles_move:  # their centres count as motion: every row's
            centers = np.asarray(obstacles, dtype=float).reshape(k, -1)
            keys = np.concatenate([goal, centers], axis=1)
        else:
            centers, keys = None, goal
        if self._world_key is None:
            self._world_key = np.zeros(keys.shape[1])
        rows = np.empty(k, dtype=np.int64)
        n = W.due_rows(np.asarray(times, dtype=float), keys, self._world_key, self._since, rows)
        if not n:
            return {}
        due = rows[:n]
        if centers is None:  # only the drawn rows' (none to stack without obstacles)
            centers = np.zeros((k, np.size(obstacles[0])))
            if centers.shape[1]:
                centers[due] = np.asarray([obstacles[r] for r in due.tolist()]).reshape(n, -1)
        drawn = min(centers.shape[1] // 3, len(self._radii))
        layout = self._world_layout(drawn)
        spheres = np.empty((k, 1 + drawn, 3))
        spheres[:, 0] = goal
        spheres[:, 1:] = centers[:, : 3 * drawn].reshape(k, drawn, 3)
        out = np.empty(n * layout.size, dtype=np.uint8)
        bounds = np.empty((n, 2), dtype=np.int64)
        end = W.encode_spheres(
            np.asarray(stamps, dtype=np.int64), spheres, due, *layout.encoding, out, bounds
        )
        data = out[:end].tobytes()
        return {r: data[a:b] for r, (a, b) in zip(due.tolist(), bounds.tolist(), strict=True)}

    def _world_layout(self, drawn: int) -> _WorldLayout:
        """The compiled layout of the goal and the first ``drawn`` obstacles, kept."""
        try:
            return self._world_layouts[drawn]
        except KeyError:
            pass
        goal = SceneEntity(frame_id=WORLD_FRAME, id="goal").encode()
        big = W.sphere_encoding(2 * SUCCESS_RADIUS, M.GOAL_COLOR)
        dot = W.sphere_encoding(0.01, M.GOAL_DOT_COLOR)
        entities = [(goal, [(big, 0), (dot, 0)])]
        if len(self._radii):
            obstacle = SceneEntity(frame_id=WORLD_FRAME, id="obstacles").encode()
            radii = self._radii.tolist()
            spheres = [
                (W.sphere_encoding(2 * radii[j], M.OBSTACLE_COLOR), 1 + j) for j in range(drawn)
            ]
            entities.append((obstacle, spheres))
        encoding = W.spheres_encoding(entities)
        size = len(encoding.entities) + len(encoding.spheres)  # and what a step adds
        size += 20 * len(encoding.entity_ends) + 36 * len(encoding.sphere_entity)
        layout = self._world_layouts[drawn] = _WorldLayout(encoding, size)
        return layout

    def publish_reference(self, t: float) -> None:
        """Log :meth:`reference_update`."""
        self.reference.base.log(self.reference_update(t), round(t * 1e9))

    def reference_update(self, t: float) -> bytes:
        """The ``/scene/reference`` message at ``t`` [s]; the line is due again a second later."""
        self.next_reference = t + 1.0
        return W.line_update(self._reference_line, round(t * 1e9), self._reference_points)

    def add_path_point(self, x: float, y: float, z: float) -> None:
        """One more point of the executed TCP path (drawn at the next :meth:`publish_path`).

        Encoded now and kept: a path update writes the points so far without encoding any again
        (each point's bytes depend on it alone).
        """
        self._path_points += W.point_field(x, y, z)

    def publish_path(self, t: float) -> None:
        """Log :meth:`path_update`, if any."""
        update = self.path_update(t)
        if update is not None:
            self.path.base.log(update, round(t * 1e9))

    def path_update(self, t: float) -> bytes | None:
        """The executed TCP path so far, ``/scene/path``'s message (None before a first point)."""
        if not self._path_points:
            return None
        return W.line_update(self._path_line, round(t * 1e9), self._path_points)

    def plan_update(self, t: float, plan: Any) -> bytes | None:
        """The method's current plan as ``/scene/plan``'s message, if it is an ``(k, >=3)`` array.

        A :class:`~amex.core.lazy.LazyRows` plan is computed at the rows drawn alone (the same
        points), another :class:`~amex.core.lazy.Lazy` whole. None: no plan to draw.
        """
        if isinstance(plan, LazyRows):
            rows = self._rows(plan.length)
            plan, rows = plan.take(rows), None
        else:
            if isinstance(plan, Lazy):
                plan = plan.compute()
            rows = self._rows(len(plan)) if isinstance(plan, np.ndarray) and plan.ndim else None
        return self._plan_message(t, plan, rows)

    def plan_updates(self, times: Sequence[float], plans: Sequence[Any]) -> list[bytes | None]:
        """:meth:`plan_update` of each ``(times[j], plans[j])``, the same messages.

        The drawn rows of :class:`~amex.core.lazy.LazyRows` plans of one group (CR's, MPPI's:
        the TCP positions of knots) are computed in one call, on their knots stacked: a batch's
        ten plans cost one call of the kinematics instead of ten (issue #29).
        """
        out: list[bytes | None] = [None] * len(plans)
        groups: dict[Any, list[int]] = {}
        for j, plan in enumerate(plans):
            if isinstance(plan, LazyRows) and plan.group is not None:
                groups.setdefault(plan.group, []).append(j)
            else:
                out[j] = self.plan_update(times[j], plan)
        for members in groups.values():
            parts = []
            for j in members:
                plan = plans[j]
                rows = self._rows(plan.length)
                parts.append(plan.source if rows is None else plan.source[rows])
            points = plans[members[0]].map(np.concatenate(parts))
            if isinstance(points, np.ndarray) and points.ndim == 2 and points.shape[1] >= 3:
                ends = np.cumsum([len(part) for part in parts]).tolist()
                stamps = [round(times[j] * 1e9) for j in members]
                updates = W.line_updates(self._plan_line, stamps, points, ends)
                for j, update in zip(members, updates, strict=True):
                    out[j] = update
        return out

    def _plan_message(self, t: float, plan: Any, rows: np.ndarray | None) -> bytes | None:
        """``/scene/plan``'s message of ``plan``'s ``rows`` (None: all), if it is (k, >= 3)."""
        if not (isinstance(plan, np.ndarray) and plan.ndim == 2 and plan.shape[1] >= 3):
            return None
        points = W.line_points(plan if rows is None else plan[rows])
        return W.line_update(self._plan_line, round(t * 1e9), points)

    def _rows(self, k: int) -> np.ndarray | None:
        """The rows drawn of a plan of ``k`` (:func:`amex.log.messages.point_rows`), kept."""
        try:
            return self._plan_rows[k]
        except KeyError:
            rows = self._plan_rows[k] = M.point_rows(k, self._max_line_points)
            return rows


class _Look(NamedTuple):
    """What the scenes of logs of one method and obstacles' radii share (:func:`_look`)."""

    lines: tuple[W.LineEncoding, W.LineEncoding, W.LineEncoding]  # reference, path, plan
    world_layouts: dict[int, _WorldLayout]  # drawn obstacles -> the world update's layout


@functools.lru_cache(maxsize=16)
def _look(method: str, radii: tuple[float, ...]) -> _Look:
    """The lines' encodings and the world updates' layouts (filled as they are first drawn).

    Pure functions of ``method`` (the colours) and ``radii``: made once for a run's logs
    instead of once per log (~0.1 ms of the SDK's encoders a log, issue #29).
    """
    lines = (
        W.line_encoding("reference", M.REFERENCE_COLOR, 2.0),
        W.line_encoding("tcp_path", M.path_color(method), 3.0),
        W.line_encoding("plan", M.plan_color(method), 3.0),
    )
    return _Look(lines, {})


class _WorldLayout(NamedTuple):
    """The compiled layout of a ``/scene/world`` message, and a bound on its size [bytes]."""

    encoding: W.SpheresEncoding
    size: int


def _scene_channel(topic: str, context: foxglove.Context) -> foxglove.Channel:
    """A channel of pre-encoded ``foxglove.SceneUpdate`` messages (the typed channel's schema)."""
    return protobuf_channel(topic, SceneUpdate, context)
