"""The live page (viser): the arm, the scene with draggable gizmos, the method's numbers and plot.

Scene: the arm with its visual meshes (:class:`~amex.app.live.robot_view.RobotView`), the goal
(gold: the 0.03 m success sphere, a gizmo to drag it by its arrows or planes; a small dot where
the method perceives it), the obstacles (black, one gizmo each), the reference plan (red), the
method's current plan (its colour, lighter) and the executed TCP path (its colour), colours of
:mod:`amex.core.palette`. Panel: the method (every registered one, plugins included), the scene
buttons, pause / step, record, the speed factor, the goal's and obstacles' exact positions, and
read-only texts a test can read by their labels (time, phase, distance to the goal, the method's
step time, real time, status, recording) above a live plot of the distance and the phase.

A publisher thread copies the session's state to the page about 25 times a second (the paths and
the plan 5 times); the episode's loop never waits for the page.

Over 400 lines on purpose: one page, whose 3-D scene and panel controls are built from the same
session state and callbacks.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import replace
from typing import Any

import numpy as np

from amex.app.live.robot_view import RobotView
from amex.app.live.session import LiveSession, LiveState
from amex.core.errors import AmexError
from amex.core.palette import (
    GOAL_COLOR,
    NEUTRAL_COLOR,
    OBSTACLE_COLOR,
    REFERENCE_COLOR,
    lighter,
    method_color,
    method_label,
    rgb255,
)
from amex.log.scene import SUCCESS_RADIUS

log = logging.getLogger(__name__)
GIZMO_SCALE = 0.12  # [m] length of a gizmo's arrows
FRAME_RATE = 25.0  # [1/s] page updates
SLOW_EVERY = 5  # frames between updates of the paths, the plan and the plot
MAX_SEGMENTS = 600  # segments of a drawn path
#: The labels of the read-only texts (tests read them from the page).
TEXTS = ("time [s]", "phase", "distance to goal [m]", "method step [ms]", "real time", "status",
         "recording")  # fmt: skip
#: Every colour the page draws with, by what it shows (``tests/live/test_colors.py``).
COLORS = {
    "goal": GOAL_COLOR,
    "goal_seen": GOAL_COLOR,
    "obstacle": OBSTACLE_COLOR,
    "reference": REFERENCE_COLOR,
    "grid": NEUTRAL_COLOR,
}


def segments(points: np.ndarray, max_segments: int = MAX_SEGMENTS) -> np.ndarray:
    """A polyline through ``points`` (k, 3) as viser's line segments, shape (m, 2, 3)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) < 2:
        return np.zeros((0, 2, 3))
    step = max(1, math.ceil((len(points) - 1) / max_segments))
    pts = (
        np.concatenate([points[::step], points[-1:]])
        if (len(points) - 1) % step
        else points[::step]
    )
    return np.stack([pts[:-1], pts[1:]], axis=1)


def camera_pose(start: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A camera position and look-at point that see the arm and the motion from the side [m].

    The camera looks at the middle of start and goal horizontally at right angles to the motion,
    from the side away from the robot's base at the origin, and from a little above.
    """
    center = (np.asarray(start) + np.asarray(goal)) / 2
    center[2] = max(center[2] * 0.7, 0.2)
    motion = (np.asarray(goal) - np.asarray(start))[:2]
    side = np.array([motion[1], -motion[0]]) if np.linalg.norm(motion) > 1e-6 else center[:2]
    if side @ center[:2] < 0:
        side = -side
    side = side / max(np.linalg.norm(side), 1e-9)
    position = center + np.array([side[0] * 0.95, side[1] * 0.95, 0.35])
    return position, center


class LivePage:
    """The page of ``session`` on ``server`` (module notes)."""

    def __init__(self, server: Any, session: LiveSession) -> None:
        self.server, self.session = server, session
        self._closed = threading.Event()
        self._dragging = False
        self._notice = ("", 0.0)  # a message shown as the status until a time
        self._episode = -1
        self._frame = 0
        server.gui.configure_theme(control_width="large")
        goal = self._build_scene()
        self._build_panel(goal)
        server.on_client_connect(self._on_connect)
        self._thread = threading.Thread(target=self._publish, name="amex-live-page", daemon=True)

    def _build_scene(self) -> np.ndarray:
        """The 3-D scene: grid, robot, reference, plan and path lines, the goal and its gizmo."""
        server, session = self.server, self.session
        scene = server.scene
        robot = session.context.robot
        plan = session.context.plan
        self._grid = scene.add_grid(
            "/grid", width=2.0, height=2.0, cell_color=rgb255(NEUTRAL_COLOR)
        )
        self.robot = RobotView(server, robot, "/robot")
        reference = np.asarray(plan.y)[:, :3]
        self._reference_line = scene.add_line_segments(
            "/reference", segments(reference), colors=rgb255(REFERENCE_COLOR), thickness=0.004
        )
        self._plan_line = scene.add_line_segments(
            "/plan", np.zeros((1, 2, 3)), colors=(0, 0, 0), thickness=0.004, visible=False
        )
        self._path_line = scene.add_line_segments(
            "/path", np.zeros((1, 2, 3)), colors=(0, 0, 0), thickness=0.006, visible=False
        )
        goal = session.goal_now() if session.state.episode else np.asarray(reference[-1])
        self.goal_gizmo = scene.add_transform_controls(
            "/goal", scale=GIZMO_SCALE, line_width=4.0, disable_rotations=True, position=goal,
            depth_test=False,
        )  # fmt: skip
        self._goal_sphere = scene.add_icosphere(
            "/goal/sphere", radius=SUCCESS_RADIUS, color=rgb255(GOAL_COLOR), opacity=0.45
        )
        self._goal_dot = scene.add_icosphere("/goal/dot", radius=0.006, color=rgb255(GOAL_COLOR))
        self._goal_seen = scene.add_icosphere(
            "/goal_seen", radius=0.004, color=rgb255(GOAL_COLOR), opacity=0.8
        )
        self.goal_gizmo.on_update(self._on_goal_drag)
        self.obstacle_gizmos: list[Any] = []
        self._obstacle_spheres: list[Any] = []
        self._start, self._goal_ref = reference[0], reference[-1]
        return goal

    def _build_panel(self, goal: np.ndarray) -> None:
        """The side panel: method and scene buttons, goal and obstacle fields, texts and plot."""
        session, gui = self.session, self.server.gui
        with gui.add_folder("Method and scene"):
            self.method = gui.add_dropdown(
                "method", options=tuple(session.method_names), initial_value=session.state.method
            )
            self.method.on_update(self._on_method)
            self._button("Restart", lambda: session.reset("restart"),
                         hint="the scene as it is, from the start pose")  # fmt: skip
            self._button("New environment", lambda: session.reset("next"),
                         hint="the task's next environment")  # fmt: skip
            self._button("Reference scene", lambda: session.reset("reference"),
                         hint="Task 0: the reference plan's own goal, no obstacle")  # fmt: skip
            self.pause = self._button("Pause", self._on_pause)
            self._button("Step", session.step, hint="one outer step while paused")
            self.record = self._button(
                "Record", self._on_record, hint="restart the scene and write it as an MCAP log"
            )
            self.speed = gui.add_slider("speed", min=0.1, max=2.0, step=0.05,
                                        initial_value=session.speed)  # fmt: skip
            self.speed.on_update(lambda e: session.set_speed(self.speed.value))
        self._scene_folder = gui.add_folder("Goal and obstacles")
        with self._scene_folder:
            self.goal_field = gui.add_vector3("goal [m]", initial_value=tuple(goal), step=0.001)
            self.goal_field.on_update(self._on_goal_field)
            self.obstacle_fields: list[Any] = []
        with gui.add_folder("Execution"):
            self.texts = {label: gui.add_text(label, initial_value="", disabled=True)
                          for label in TEXTS}  # fmt: skip
            self.warning = gui.add_markdown("")
            self.plot = gui.add_uplot(
                data=(np.zeros(1), np.zeros(1), np.zeros(1)),
                series=(
                    {"label": "t [s]"},
                    {"label": "distance [m]", "stroke": NEUTRAL_COLOR, "width": 2, "scale": "m"},
                    {
                        "label": "phase",
                        "stroke": method_color(session.state.method),
                        "width": 2,
                        "scale": "phase",
                    },
                ),  # fmt: skip
                scales={"x": {"time": False}, "m": {"auto": True}, "phase": {"range": [0, 1]}},
                axes=({}, {"scale": "m"}, {"scale": "phase", "side": 1, "grid": {"show": False}}),
                aspect=1.6,
            )

    # -- wiring -----------------------------------------------------------------------------
    def _button(self, label: str, action: Any, hint: str | None = None) -> Any:
        button = self.server.gui.add_button(label, hint=hint)
        button.on_click(lambda event: action())
        return button

    def start(self) -> None:
        """Start publishing the session's state."""
        self._thread.start()

    def close(self) -> None:
        """Stop publishing."""
        self._closed.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)

    def _on_connect(self, client: Any) -> None:
        position, look_at = camera_pose(self._start, self._goal_ref)
        client.camera.up_direction = (0.0, 0.0, 1.0)
        client.camera.position = tuple(position)
        client.camera.look_at = tuple(look_at)

    def _on_goal_drag(self, event: Any) -> None:
        phase = getattr(event, "phase", "update")
        self._dragging = phase != "end"
        self.session.set_goal(np.asarray(event.target.position))

    def _on_goal_field(self, event: Any) -> None:
        if event.client is None:  # the page's own update
            return
        self.session.set_goal(np.asarray(self.goal_field.value))

    def _on_obstacle_drag(self, k: int, event: Any) -> None:
        self.session.set_obstacle(k, np.asarray(event.target.position))

    def _on_obstacle_field(self, k: int, event: Any) -> None:
        if event.client is None:
            return
        self.session.set_obstacle(k, np.asarray(self.obstacle_fields[k].value))

    def _on_method(self, event: Any) -> None:
        if event.client is None or self.method.value == self.session.state.method:
            return
        try:
            self.session.switch_method(self.method.value)
        except AmexError as e:  # its configuration does not compose: say so on the page
            message = f"cannot switch to {self.method.value}: {e}"[:300]
            self._notice = (message, time.monotonic() + 8.0)

    def _on_pause(self) -> None:
        if self.session.paused:
            self.session.resume()
        else:
            self.session.pause()
        self.pause.label = "Resume" if self.session.paused else "Pause"

    def _on_record(self) -> None:
        if self.session.state.recording:
            self.session.stop_recording()
        else:
            self.session.start_recording()

    def colors(self) -> list[tuple[str, str]]:
        """What the page draws in which colour, read back from its scene and plot handles.

        ``(role, #rrggbb)``: roles ``goal``, ``obstacle``, ``reference``, ``neutral`` and
        ``method`` (the running method's path and plan, and its phase in the plot).
        """
        uses = [
            ("reference", _hex(self._reference_line.colors)),
            ("goal", _hex(self._goal_sphere.color)),
            ("goal", _hex(self._goal_dot.color)),
            ("goal", _hex(self._goal_seen.color)),
            ("neutral", _hex(self._grid.cell_color)),
            ("neutral", str(self.plot.series[1]["stroke"])),
            ("method", str(self.plot.series[2]["stroke"])),
        ]
        uses += [("obstacle", _hex(sphere.color)) for sphere in self._obstacle_spheres]
        uses += [("method", _hex(line.colors)) for line in (self._path_line, self._plan_line)
                 if line.visible]  # fmt: skip
        return uses

    # -- publishing -------------------------------------------------------------------------
    def _publish(self) -> None:
        period = 1.0 / FRAME_RATE
        failed: set[str] = set()
        while not self._closed.wait(period):
            try:
                self.update(self.session.state)
            except Exception as e:  # a client gone mid-update: the next frame; say it once
                if type(e).__name__ not in failed:
                    failed.add(type(e).__name__)
                    log.warning("live page: an update failed: %s: %s", type(e).__name__, e)

    def update(self, state: LiveState) -> None:
        """Show ``state`` (one frame)."""
        if state.episode != self._episode:
            self._new_episode(state)
        if len(state.q):
            self.robot.show(state.q)
        scenario = self.session.scenario
        if scenario is not None and scenario.now == state.t:  # as moved by hand since, if paused
            goal = np.asarray(scenario.goal_at(state.t))
            obstacles = np.asarray(scenario.obstacles_at(state.t))
            distance = float(np.linalg.norm(state.tcp - goal))
            state = replace(state, goal=goal, obstacles=obstacles, distance=distance)
        goal = state.goal
        if (
            not self._dragging
            and np.max(np.abs(np.asarray(self.goal_gizmo.position) - goal)) > 1e-6
        ):
            self.goal_gizmo.position = tuple(goal)
        self._goal_seen.position = tuple(state.goal_seen)
        if np.max(np.abs(np.asarray(self.goal_field.value) - goal)) > 5e-4:
            self.goal_field.value = tuple(round(float(x), 4) for x in goal)
        for k, centre in enumerate(state.obstacles[: len(self.obstacle_gizmos)]):
            gizmo = self.obstacle_gizmos[k]
            if np.max(np.abs(np.asarray(gizmo.position) - centre)) > 1e-6:
                gizmo.position = tuple(centre)
            if np.max(np.abs(np.asarray(self.obstacle_fields[k].value) - centre)) > 5e-4:
                self.obstacle_fields[k].value = tuple(round(float(x), 4) for x in centre)
        self._texts(state)
        self._frame += 1
        if self._frame % SLOW_EVERY == 0:
            self._slow(state)

    def _texts(self, state: LiveState) -> None:
        pace = state.pace
        values = {
            "time [s]": f"{state.t:.2f}",
            "phase": f"{state.phase_name} = {state.phase:.3f}" if state.phase_name else "-",
            "distance to goal [m]": f"{state.distance:.4f}",
            "method step [ms]": f"{state.step_time * 1e3:.3f}" if math.isfinite(state.step_time)
            else "-",
            "real time": _pace_text(pace, self.session.speed, state.status),
            "status": f"{method_label(state.method)}, task {state.task} env {state.env}: "
            f"{state.status}",
            "recording": state.recording or (
                f"last: {self.session.last_log}" if self.session.last_log else "-"),
        }  # fmt: skip
        if time.monotonic() < self._notice[1]:
            values["status"] = self._notice[0]
        for label, value in values.items():
            if self.texts[label].value != value:
                self.texts[label].value = value
        warning = "" if pace.keeps_pace or state.status != "running" else (
            f"**Not real time**: the loop runs at {pace.realtime_factor:.2f}x (speed "
            f"{self.session.speed:g}x); it needs {100 * pace.load:.0f} % of its time"
            + (" (a slow method: lower the speed)" if pace.load >= 0.8 else
               " (other processes take the CPU)") + "."
        )  # fmt: skip
        if self.warning.content != warning:
            self.warning.content = warning
        self.record.label = "Stop recording" if state.recording else "Record"
        self.pause.label = "Resume" if self.session.paused else "Pause"

    def _slow(self, state: LiveState) -> None:
        color = method_color(state.method)
        path = np.array(self.session.path) if self.session.path else np.zeros((0, 3))
        if len(path) >= 2:
            _set_line(self._path_line, segments(path), color)
        plan = self.session.plan.points()
        if plan is not None and len(plan) >= 2:
            _set_line(self._plan_line, segments(plan), lighter(color))
        else:
            self._plan_line.visible = False
        history = list(self.session.history)
        if len(history) >= 2:
            t, d, s = (np.array(c, dtype=float) for c in zip(*history, strict=True))
            s = np.where(np.isfinite(s), s, 0.0)
            if "index" in state.phase_name:
                s = s / max(len(self.session.context.plan.y) - 1, 1)
            self.plot.data = (t, d, s)

    def _new_episode(self, state: LiveState) -> None:
        self._episode = state.episode
        self._path_line.visible = False
        self._plan_line.visible = False
        if self.method.value != state.method:
            self.method.value = state.method
        series = list(self.plot.series)
        if series[2].get("stroke") != method_color(state.method):
            series[2] = {**series[2], "stroke": method_color(state.method)}
            self.plot.series = tuple(series)
        n = len(state.radii)
        if n != len(self.obstacle_gizmos):
            self._obstacles(state)

    def _obstacles(self, state: LiveState) -> None:
        for handle in [*self.obstacle_gizmos, *self._obstacle_spheres, *self.obstacle_fields]:
            handle.remove()
        self.obstacle_gizmos, self._obstacle_spheres, self.obstacle_fields = [], [], []
        centres = state.obstacles if len(state.obstacles) == len(state.radii) else np.zeros(
            (len(state.radii), 3))  # fmt: skip
        for k, (centre, radius) in enumerate(zip(centres, state.radii, strict=True)):
            gizmo = self.server.scene.add_transform_controls(
                f"/obstacle_{k}", scale=GIZMO_SCALE, line_width=4.0, disable_rotations=True,
                position=tuple(centre), depth_test=False,
            )  # fmt: skip
            sphere = self.server.scene.add_icosphere(
                f"/obstacle_{k}/sphere", radius=float(radius), color=rgb255(OBSTACLE_COLOR),
                opacity=0.8,
            )  # fmt: skip
            gizmo.on_update(lambda event, k=k: self._on_obstacle_drag(k, event))
            with self._scene_folder:
                field = self.server.gui.add_vector3(
                    f"obstacle {k + 1} [m]", initial_value=tuple(centre), step=0.001
                )
            field.on_update(lambda event, k=k: self._on_obstacle_field(k, event))
            self.obstacle_gizmos.append(gizmo)
            self._obstacle_spheres.append(sphere)
            self.obstacle_fields.append(field)


def _hex(color: Any) -> str:
    """A viser colour (RGB integers, or an array of them per point) as ``#rrggbb``."""
    r, g, b = (int(c) for c in np.asarray(color).reshape(-1, 3)[0])
    return f"#{r:02x}{g:02x}{b:02x}"


def _set_line(handle: Any, points: np.ndarray, color: str) -> None:
    """Show line segments ``points`` (m, 2, 3) in ``color`` (viser wants a colour per point)."""
    handle.points = points
    handle.colors = np.broadcast_to(np.array(rgb255(color), dtype=np.uint8), points.shape).copy()
    handle.visible = True


def _pace_text(pace: Any, speed: float, status: str) -> str:
    """``1.00x of real time (speed 1x), load 8 %``, or what keeps it from being real time."""
    if status != "running":
        return f"- ({status})"
    factor = pace.realtime_factor
    if not math.isfinite(factor):
        return "measuring"
    if pace.keeps_pace:
        verdict = "keeps pace"
    elif pace.load < 0.8:
        verdict = "BEHIND: the machine is busy (the loop itself needs less than its time)"
    else:
        verdict = "CANNOT KEEP UP: the loop needs more than its time"
    return f"{factor:.2f}x (speed {speed:g}x), load {100 * pace.load:.0f} %: {verdict}"
