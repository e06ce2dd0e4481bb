"""``amex-log video``: an episode log as an MP4 film, or 2-3 logs of one environment side by side.

Each frame is a MuJoCo offscreen render (:mod:`amex.log.render`) of the logged arm at that instant
of simulation time, drawn with the robot's visual meshes (``geometry="collision"``, the CLI's
``--capsules``: its collision shapes), with the goal (gold: the 0.03 m success sphere and its path
so far), the obstacles (black spheres; a moving obstacle's whole path as a thin line), the
reference plan (red) and the executed TCP path so far, in the method's colour
(:mod:`amex.core.palette`). The camera frames the whole arm over the episode and the scene
(:func:`~amex.log.render.frame_points`). The caption sits in a band above the scene and the outcome
in one below it, so that no text covers the robot: the method, the time and the method's phase
(AMEX s, DMP x, the tracked index), and at the end the outcome. Episodes that ended earlier than
the longest one hold their last frame. A log recorded by ``amex-live`` (metadata ``live``) draws
its goal where the method saw it (``/goal``), since a hand moved it. Frames are encoded as H.264
(yuv420p, plays everywhere) by the ffmpeg that imageio-ffmpeg ships.

Cost: about 15 ms (capsules) to 30 ms (the Panda's meshes) per 640 x 480 panel and frame with
Mesa's software EGL on one core, so a 6 s episode at 30 frames/s takes ~4-8 s; ~80-150 kB per
second of film.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from amex.core.durable import publish_new
from amex.core.errors import LogError, LogExistsError, WriteError
from amex.core.palette import GOAL_COLOR, OBSTACLE_COLOR, REFERENCE_COLOR, method_color, rgba
from amex.core.palette import method_label as label_of
from amex.log.reader import LogData, read_log
from amex.log.render import (
    BAND_RGB,
    SceneDrawer,
    aim_camera,
    arm_model,
    draw_caption,
    frame_points,
    gl_context,
    joint_addresses,
    split_viewport,
)
from amex.log.scene import SUCCESS_RADIUS
from amex.sim.scenario import Scenario

PHASE_NAMES = {"s": "phase s", "phase": "phase x", "index": "index"}  # as the layout's plot
MAX_PANELS = 3
FRAME_MARGIN = 1.05  # the bounding sphere of the arm and the scene, plus the links' own size
BAND = 30  # [px] height of the caption band above the scene and the outcome band below it
__all__ = ["BAND", "BAND_RGB", "render_video", "track_of"]


@dataclass(frozen=True)
class EpisodeTrack:
    """What a film needs of one log: the arm's motion, the scene, the caption's numbers."""

    method: str
    urdf_path: str
    package_dirs: list[str]
    joint_names: list[str]
    t: np.ndarray  # (n,) times of the joint states [s]
    q: np.ndarray  # (n, joints) [rad]
    tcp_t: np.ndarray  # (m,) [s]
    tcp: np.ndarray  # (m, 3) [m]
    reference: np.ndarray  # (N + 1, 3) [m]
    scenario: Scenario
    phase_name: str
    phase_t: np.ndarray  # (k,) [s]
    phase: np.ndarray  # (k,)
    outcome: dict[str, Any]
    environment: tuple[Any, ...]  # (task, env, seed)
    goal_t: np.ndarray | None = None  # (g,) [s]: a live log's goal samples (else the scenario's)
    goal: np.ndarray | None = None  # (g, 3) [m]

    def goal_at(self, t: float) -> np.ndarray:
        """The goal at ``t`` [s]: the logged one of a live log, else the scenario's."""
        if self.goal is not None and self.goal_t is not None and len(self.goal):
            return self.goal[_at(self.goal_t, t)]
        return self.scenario.goal_at(t)

    def goal_path(self, t: float, n: int = 40) -> np.ndarray:
        """The goal's path from 0 to ``t`` [s] (the scenario's stops moving at its stop time)."""
        if self.goal is not None and self.goal_t is not None and len(self.goal):
            return self.goal[: _at(self.goal_t, t) + 1]
        times = np.linspace(0.0, min(t, self.scenario.goal_stop_time), n)
        return np.array([self.scenario.goal_at(g) for g in times])

    @property
    def end(self) -> float:
        """When the episode ended: its final time, else its last logged state [s]."""
        last = float(self.t[-1]) if len(self.t) else 0.0
        final = self.outcome.get("final_time")
        return max(last, float(final)) if isinstance(final, (int, float)) else last


def scenario_of(data: LogData) -> Scenario:
    """The environment recorded in a log's ``scenario`` metadata."""
    s = data.metadata.get("scenario")
    if not s:
        raise LogError(f"{data.path} has no scenario metadata (not an amex episode log?)")
    return Scenario(
        task=int(s["task"]),
        env=int(s["env"]),
        seed=int(s["seed"]),
        goal_start=np.asarray(s["goal_start"], dtype=float),
        goal_velocity=np.asarray(s["goal_velocity"], dtype=float),
        goal_stop_time=float(s["goal_stop_time"]),
        goal_axis=np.asarray(s["goal_axis"], dtype=float),
        obstacle_start=np.asarray(s["obstacle_start"] or np.zeros((0, 3)), dtype=float),
        obstacle_velocity=np.asarray(s["obstacle_velocity"] or np.zeros((0, 3)), dtype=float),
        obstacle_radii=np.asarray(s["obstacle_radii"] or [], dtype=float),
    )


def track_of(data: LogData) -> EpisodeTrack:
    """Read what :func:`render_video` needs from a log."""
    robot = data.metadata.get("robot", {})
    if not robot.get("urdf_path") or not data.messages.get("/joint_states"):
        raise LogError(f"{data.path} has no robot metadata or joint states to film")
    episode = data.metadata.get("episode", {})
    first = [m.data for m in data.messages.get("/method", [])[:5] if isinstance(m.data, dict)]
    phase_key = next((k for k in PHASE_NAMES if any(k in d for d in first)), "")
    live = bool(episode.get("live")) and bool(data.messages.get("/goal"))
    return EpisodeTrack(
        method=str(episode.get("method", "?")),
        urdf_path=str(robot["urdf_path"]),
        package_dirs=[str(d) for d in robot.get("package_dirs") or []],
        joint_names=[str(j) for j in robot.get("joint_names", [])],
        t=data.times("/joint_states"),
        q=data.joints("position"),
        tcp_t=data.times("/tcp"),
        tcp=data.series("/tcp", "position").reshape(-1, 3),
        reference=data.reference_path(),
        scenario=scenario_of(data),
        phase_name=PHASE_NAMES.get(phase_key, ""),
        phase_t=data.times("/method") if phase_key else np.zeros(0),
        phase=data.series("/method", phase_key) if phase_key else np.zeros(0),
        outcome=data.outcome or {},
        environment=tuple(episode.get(k) for k in ("task", "env", "seed")),
        goal_t=data.times("/goal") if live else None,
        goal=data.series("/goal", "position").reshape(-1, 3) if live else None,
    )


def _at(times: np.ndarray, t: float) -> int:
    """Index of the last sample at or before ``t`` (0 before the first)."""
    return max(int(np.searchsorted(times, t + 1e-9, side="right")) - 1, 0)


def _outcome_text(outcome: dict[str, Any]) -> str:
    if "success" not in outcome:
        return str(outcome.get("status", "no outcome logged"))
    verdict = "reached" if outcome["success"] else "missed"
    extra = ", collided" if outcome.get("collided") else ""
    return f"{verdict}: {outcome['final_distance']:.3f} m at {outcome['final_time']:.2f} s{extra}"


class _Panel:
    """One episode's view: its model data, scene and camera."""

    def __init__(self, track: EpisodeTrack, width: int, height: int, geometry: str) -> None:
        import mujoco

        self.track = track
        self.model = arm_model(
            track.urdf_path, samples=0, package_dirs=track.package_dirs, geometry=geometry
        )
        self.model.vis.global_.offwidth, self.model.vis.global_.offheight = width, height
        self.data = mujoco.MjData(self.model)
        self.addresses = joint_addresses(self.model, track.joint_names)
        self.scene = mujoco.MjvScene(self.model, maxgeom=4000)
        self.camera = mujoco.MjvCamera()
        self.option = mujoco.MjvOption()
        s = track.scenario
        moving = np.any(s.obstacle_velocity != 0, axis=1) if s.n_obstacles else np.zeros(0, bool)
        times = np.linspace(0.0, max(track.end, 1e-3), 60)
        self.obstacle_paths = [
            np.array([s.obstacles_at(t)[k] for t in times]) for k in np.flatnonzero(moving)
        ]
        self.color = method_color(track.method)

    def look_points(self) -> np.ndarray:
        """What the camera must see: the arm over the episode, paths, goal and obstacles."""
        track, s = self.track, self.track.scenario
        goals = track.goal_path(track.end)
        obstacles = [s.obstacles_at(t) for t in (0.0, track.end)]
        every = max(1, len(track.q) // 20)
        arm = frame_points(self.model, self.addresses, track.q, every)
        return np.concatenate([track.reference, track.tcp, *obstacles, goals, arm])

    def draw(self, context: Any, t: float, viewport: Any) -> None:
        import mujoco

        track, s = self.track, self.track.scenario
        t_show = min(t, track.end)
        q = track.q[_at(track.t, t_show)]
        valid = self.addresses >= 0
        self.data.qpos[self.addresses[valid]] = q[: len(self.addresses)][valid]
        mujoco.mj_forward(self.model, self.data)
        mujoco.mjv_updateScene(
            self.model,
            self.data,
            self.option,
            None,
            self.camera,
            mujoco.mjtCatBit.mjCAT_ALL,
            self.scene,
        )
        draw = SceneDrawer(self.scene)
        draw.floor(np.asarray(self.camera.lookat[:2]), 4.0)
        draw.path(track.reference, rgba(REFERENCE_COLOR), 3.0, 50)
        draw.path(track.goal_path(t_show), rgba(GOAL_COLOR), 4.0, 30)
        goal = track.goal_at(t_show)
        draw.sphere(goal, SUCCESS_RADIUS, rgba(GOAL_COLOR, 0.35))
        draw.sphere(goal, 0.006, rgba(GOAL_COLOR))
        for path in self.obstacle_paths:
            draw.path(path, rgba(OBSTACLE_COLOR, 0.6), 2.0, 30)
        for center, radius in zip(s.obstacles_at(t_show), s.obstacle_radii, strict=False):
            draw.sphere(center, float(radius), rgba(OBSTACLE_COLOR, 0.85))
        upto = _at(track.tcp_t, t_show) + 1
        draw.path(track.tcp[:upto], rgba(self.color), 4.0, 80)
        scene_view, top, bottom = split_viewport(viewport, min(BAND, viewport.height // 6))
        mujoco.mjr_render(scene_view, self.scene, context)
        caption = f"{label_of(track.method)}    t = {t_show:5.2f} s"
        if track.phase_name and len(track.phase_t):
            caption += f"    {track.phase_name} = {track.phase[_at(track.phase_t, t_show)]:.3f}"
        draw_caption(context, top, caption)  # the bands: text never covers the scene
        draw_caption(context, bottom, _outcome_text(track.outcome) if t >= track.end else "")


@dataclass(frozen=True)
class VideoInfo:
    """What :func:`render_video` wrote."""

    path: Path
    frames: int
    seconds: float  # of film
    width: int
    height: int
    different_environments: bool


def render_video(
    logs: list[Path],
    output: Path,
    *,
    fps: float = 30.0,
    width: int = 640,
    height: int = 480,
    speed: float = 1.0,
    geometry: str = "visual",
) -> VideoInfo:
    """Film ``logs`` (1-3, side by side) into ``output`` (MP4, H.264); see the module notes.

    Args:
        logs: episode logs; several are shown side by side on one clock.
        output: the MP4 file to create (an existing file is never replaced).
        fps: frames per second of film.
        width: width of one panel [px] (a multiple of 16 keeps the encoder from resizing).
        height: height [px].
        speed: simulated seconds per second of film.
        geometry: the arm's ``"visual"`` meshes or its ``"collision"`` shapes.

    Raises:
        LogError: a log cannot be read or filmed; RenderError: no headless OpenGL;
        LogExistsError: ``output`` exists; WriteError: the film could not be written.
    """
    if output.exists() or output.is_symlink():
        raise LogExistsError(f"output file {output} already exists; not overwriting it")
    if not 1 <= len(logs) <= MAX_PANELS:
        raise LogError(f"give 1 to {MAX_PANELS} logs to film side by side, not {len(logs)}")
    if not (fps > 0 and speed > 0 and width >= 64 and height >= 64):
        raise LogError("need fps > 0, speed > 0 and a size of at least 64 x 64 pixels")
    tracks = [track_of(read_log(p)) for p in logs]
    end = max(track.end for track in tracks)
    frames = int(np.floor(end / speed * fps + 1e-9)) + 1
    hold = int(round(fps))  # a second on the last frame, outcome shown
    times = [min(k / fps * speed, end) if k < frames else end + 1.0 for k in range(frames + hold)]
    gl = gl_context(width, height)
    contexts: list[Any] = []
    try:
        panels = _aimed_panels(tracks, width, height, geometry)
        contexts.extend(_render_contexts(panels, width))
        output.parent.mkdir(parents=True, exist_ok=True)
        tmp = output.with_name(output.name + ".part.mp4")
        _encode(tmp, output, panels, contexts, times, fps, width, height)
        try:
            publish_new(tmp, output)
        except FileExistsError:
            message = f"output file {output} appeared while filming; not replaced"
            raise LogExistsError(message) from None
    finally:
        for context in contexts:
            context.free()
        gl.free()
    environments = {track.environment for track in tracks}
    return VideoInfo(
        output, len(times), len(times) / fps, width * len(tracks), height, len(environments) > 1
    )


def _aimed_panels(tracks: list[Any], width: int, height: int, geometry: str) -> list[_Panel]:
    """One panel per track, every camera aimed at what all of them show (one framing)."""
    panels = [_Panel(track, width, height, geometry) for track in tracks]
    look = np.concatenate([panel.look_points() for panel in panels])
    motion = tracks[0].scenario.goal_start - tracks[0].tcp[0]
    for panel in panels:
        aim_camera(panel.camera, look, motion, margin=FRAME_MARGIN)
    return panels


def _render_contexts(panels: list[_Panel], width: int) -> list[Any]:
    """A MuJoCo render context per panel (the smaller font for small panels)."""
    import mujoco

    scale = mujoco.mjtFontScale
    font = scale.mjFONTSCALE_150 if width >= 480 else scale.mjFONTSCALE_100
    return [mujoco.MjrContext(panel.model, font) for panel in panels]


def _encode(
    tmp: Path,
    output: Path,
    panels: list[_Panel],
    contexts: list[Any],
    times: list[float],
    fps: float,
    width: int,
    height: int,
) -> None:
    """The frames at ``times`` encoded into ``tmp`` (H.264); ``tmp`` is removed if that fails."""
    import imageio_ffmpeg
    import mujoco

    viewport = mujoco.MjrRect(0, 0, width, height)
    writer = imageio_ffmpeg.write_frames(
        str(tmp),
        (width * len(panels), height),
        fps=fps,
        codec="libx264",
        pix_fmt_out="yuv420p",
        macro_block_size=1,
        ffmpeg_log_level="error",
        output_params=["-crf", "23", "-preset", "veryfast"],
    )
    writer.send(None)
    rgb = np.empty((height, width, 3), dtype=np.uint8)
    written = False
    try:
        for t in times:
            row = []
            for panel, context in zip(panels, contexts, strict=True):
                mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
                panel.draw(context, t, viewport)
                mujoco.mjr_readPixels(rgb, None, viewport, context)
                row.append(np.flipud(rgb).copy())
            writer.send(np.ascontiguousarray(np.hstack(row)))
        writer.close()
        written = True
    except OSError as e:  # ffmpeg's pipe or file: a full disk, a removed directory
        raise WriteError(output, e.strerror or str(e)) from e
    finally:
        if not written:
            with contextlib.suppress(Exception):
                writer.close()
            with contextlib.suppress(OSError):
                tmp.unlink()
