"""The paper's Fig. 4 on the Panda: one Task-3 scene with the executed paths of AMEX, DMP and CR.

As in the paper: the obstacle is a black ball, the goal's start and end are yellow balls joined by
its path, the reference plan (planned without the obstacle) is red, and the executed TCP paths are
blue (AMEX), green (DMP) and white / black (CR), for the methods registered in
``amex.methods.METHODS``. Each episode is run here and logged to MCAP in a temporary directory,
then read back with :func:`amex.log.read_log` (or read from the logs given), so the figure shows
exactly what ``amex-log`` shows.

Two views: (a) a MuJoCo offscreen render of the simulated scene (the arm at the end of the first
method's episode), if an OpenGL backend works headless here (``MUJOCO_GL`` if set, then EGL,
then OSMesa; otherwise (a) says why it is missing); (b) a labelled 3-D plot, with top and side
projections below. Run ``python analysis/fig4.py [OUT_DIR]``.
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from amex.log.plot3d import set_equal_axes_3d

TASK = 3
ENV = 0  # the Task-3 environment drawn (a goal the obstacle sits right in front of)
SEED = 0
FIG4_METHODS = ("amex", "dmp", "cr")
COLORS = {"amex": "tab:blue", "dmp": "tab:green", "cr": "black", "reference": "tab:red"}
LABELS = {"amex": "AMEX", "dmp": "DMP", "cr": "CR"}
GOAL_COLOR = "gold"
CAMERA = (0.85, 155.0, -30.0)  # MuJoCo free camera: distance [m], azimuth, elevation [deg]
RENDER_RGBA = {
    "reference": (0.9, 0.1, 0.1, 1.0),
    "amex": (0.2, 0.4, 1.0, 1.0),
    "dmp": (0.1, 0.85, 0.2, 1.0),
    "cr": (1.0, 1.0, 1.0, 1.0),
    "goal": (1.0, 0.85, 0.0, 1.0),
}


@dataclass(frozen=True)
class Episode:
    """What a figure needs from one logged episode."""

    method: str
    t: np.ndarray  # (n,) [s]
    tcp: np.ndarray  # (n, 3) [m]
    goal: np.ndarray  # (n, 3) [m]
    q: np.ndarray  # (n, 7) [rad]
    reference: np.ndarray  # (N + 1, 3) [m]
    obstacles: np.ndarray  # (k, 3) [m]
    radii: np.ndarray  # (k,) [m]
    outcome: dict[str, Any]


def episode_from_log(path: Path | str) -> Episode:
    """Read the arrays of an episode log (see :mod:`amex.log.writer`)."""
    from amex.log import read_log

    data = read_log(path)
    scenario = data.metadata.get("scenario", {})
    episode = data.metadata.get("episode", {})
    return Episode(
        method=str(episode.get("method", "?")),
        t=data.times("/tcp"),
        tcp=data.series("/tcp", "position"),
        goal=data.series("/goal", "position"),
        q=data.joints("position"),
        reference=data.reference_path(),
        obstacles=np.asarray(scenario.get("obstacle_start") or np.zeros((0, 3)), float).reshape(
            -1, 3
        ),
        radii=np.asarray(scenario.get("obstacle_radii") or [], dtype=float),
        outcome=data.outcome or {},
    )


def run_logged(task: int, env: int, methods: list[str], out_dir: Path, seed: int = SEED) -> dict:
    """Run environment ``env`` of ``task`` with each method, logged into ``out_dir``; read back."""
    from amex.cli import load_config
    from amex.runner import prepare, run_one

    episodes = {}
    for name in methods:
        config = load_config([f"task={task}", f"method={name}", f"seed={seed}"])
        path = out_dir / f"task{task}_env{env:03d}_{name}.mcap"
        if not path.exists():
            run_one(config, prepare(config), env, path)
        episodes[name] = episode_from_log(path)
    return episodes


def available_methods() -> list[str]:
    """The methods of Fig. 4 that are registered now."""
    from amex.methods import METHODS

    return [m for m in FIG4_METHODS if m in METHODS]


def plot_fig4(
    out_dir: Path | str, runs_or_none: Mapping[str, Path | str] | None = None
) -> list[Path]:
    """Draw Fig. 4 into ``out_dir/fig4_task3.png``; return ``[its path]`` (like ``plot_fig2``).

    Args:
        out_dir: where the PNG goes.
        runs_or_none: MCAP logs of one Task-3 environment by method name (e.g. from
            ``amex-run task=3 method=amex episodes=1 log=full``); None runs environment
            :data:`ENV` with every registered method among AMEX, DMP and CR.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if runs_or_none:
        episodes = {name: episode_from_log(path) for name, path in runs_or_none.items()}
    else:
        with tempfile.TemporaryDirectory() as tmp:
            episodes = run_logged(TASK, ENV, available_methods(), Path(tmp))
    image, why = render_scene(episodes)
    return [_draw(episodes, image, why, out_dir / "fig4_task3.png")]


def _draw(episodes: dict[str, Episode], image: np.ndarray | None, why: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    first = next(iter(episodes.values()))
    fig = plt.figure(figsize=(13, 10), layout="constrained")
    grid = fig.add_gridspec(2, 2, height_ratios=(1.25, 1))
    ax = fig.add_subplot(grid[0, 0])
    if image is not None:
        ax.imshow(image)
        keys = [("reference", "reference plan")]
        keys += [(m, LABELS.get(m, m)) for m in episodes] + [("goal", "goal path")]
        handles = [
            Line2D([], [], color=RENDER_RGBA.get(k, (0.6, 0.6, 0.6, 1.0))[:3], lw=3, label=lab)
            for k, lab in keys
        ]
        handles.append(Line2D([], [], color="k", marker="o", ls="", ms=10, label="obstacle"))
        leg = ax.legend(
            handles=handles,
            loc="lower left",
            fontsize="small",
            facecolor="0.3",
            labelcolor="white",
            framealpha=0.8,
        )
        leg.get_frame().set_edgecolor("0.6")
        ax.set_title("(a) MuJoCo render (arm at the end of the first episode)")
    else:
        ax.text(
            0.5,
            0.5,
            f"no MuJoCo offscreen render here:\n{why}",
            ha="center",
            va="center",
            wrap=True,
            transform=ax.transAxes,
        )
        ax.set_title("(a) MuJoCo render")
    ax.set_axis_off()

    ax3 = fig.add_subplot(grid[0, 1], projection="3d")
    _paths_3d(ax3, episodes, first)
    for col, (i, j, name) in enumerate([(0, 1, "top view (x-y)"), (0, 2, "side view (x-z)")]):
        ax = fig.add_subplot(grid[1, col])
        _paths_2d(ax, episodes, first, i, j)
        ax.set_title(f"({'cd'[col]}) {name}")
    lines = [f"{LABELS.get(m, m)}: " + _outcome_text(e.outcome) for m, e in episodes.items()]
    fig.suptitle(
        f"Fig. 4 analogue: Task 3, environment {ENV}; reference plan (red, planned without "
        "obstacle) and executed TCP paths\n" + ";  ".join(lines),
        fontsize="medium",
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _outcome_text(outcome: dict[str, Any]) -> str:
    if "success" not in outcome:
        return "no outcome"
    verdict = "reached" if outcome["success"] else "missed"
    extra = ", collided" if outcome.get("collided") else ""
    return f"{verdict} ({outcome['final_distance']:.3f} m, {outcome['final_time']:.2f} s{extra})"


def _sphere(ax: Any, center: np.ndarray, radius: float, color: str, alpha: float) -> None:
    u, v = np.mgrid[0 : 2 * np.pi : 30j, 0 : np.pi : 16j]
    ax.plot_surface(
        center[0] + radius * np.cos(u) * np.sin(v),
        center[1] + radius * np.sin(u) * np.sin(v),
        center[2] + radius * np.cos(v),
        color=color,
        alpha=alpha,
        linewidth=0,
    )


def _paths_3d(ax: Any, episodes: dict[str, Episode], first: Episode) -> None:
    ax.plot(*first.reference.T, color=COLORS["reference"], lw=2, label="reference plan")
    for name, e in episodes.items():
        ax.plot(*e.tcp.T, color=COLORS.get(name, "0.5"), lw=2, label=LABELS.get(name, name))
    goal = first.goal
    ax.plot(*goal.T, color=GOAL_COLOR, lw=3, label="goal path")
    ax.scatter(
        *np.stack([goal[0], goal[-1]]).T,
        color=GOAL_COLOR,
        edgecolor="k",
        s=80,
        depthshade=False,
        label="goal start / end",
    )
    for c, r in zip(first.obstacles, first.radii, strict=False):
        _sphere(ax, c, r, "black", 0.45)
    ax.plot([], [], color="black", lw=8, alpha=0.5, label="obstacle")
    ax.scatter(*first.tcp[0], color="k", marker="s", s=30, depthshade=False, label="start")
    points = np.concatenate([first.reference, goal, *(e.tcp for e in episodes.values())])
    set_equal_axes_3d(ax, points, pad=1.05)
    ax.view_init(elev=25, azim=-125)
    ax.set_title("(b) task space, 3-D (legend in (c))")


def _paths_2d(ax: Any, episodes: dict[str, Episode], first: Episode, i: int, j: int) -> None:
    from matplotlib.patches import Circle

    ax.plot(
        first.reference[:, i],
        first.reference[:, j],
        color=COLORS["reference"],
        lw=2,
        label="reference plan",
    )
    for name, e in episodes.items():
        ax.plot(
            e.tcp[:, i],
            e.tcp[:, j],
            color=COLORS.get(name, "0.5"),
            lw=2,
            label=LABELS.get(name, name),
        )
    goal = first.goal
    ax.plot(goal[:, i], goal[:, j], color=GOAL_COLOR, lw=3, label="goal path")
    ax.scatter(
        goal[[0, -1], i],
        goal[[0, -1], j],
        color=GOAL_COLOR,
        edgecolor="k",
        s=80,
        zorder=5,
        label="goal start / end",
    )
    for c, r in zip(first.obstacles, first.radii, strict=False):
        ax.add_patch(Circle((c[i], c[j]), r, color="black", alpha=0.4, label="obstacle"))
    ax.scatter(
        first.tcp[0, i], first.tcp[0, j], color="k", marker="s", s=30, zorder=5, label="start"
    )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="xyz"[i] + " [m]", ylabel="xyz"[j] + " [m]")
    ax.grid(alpha=0.3)
    if i == 0 and j == 1:
        ax.legend(loc="best", fontsize="small")


def render_scene(episodes: dict[str, Episode], width: int = 960, height: int = 720):
    """MuJoCo offscreen render of the scene with the paths drawn in; (image, "") or (None, why)."""
    errors = []
    backends = [os.environ.get("MUJOCO_GL", "").lower(), "egl", "osmesa"]
    for backend in dict.fromkeys(b for b in backends if b in ("egl", "osmesa", "glfw")):
        try:
            return _render(episodes, backend, width, height), ""
        except Exception as e:  # no display, no libEGL/libOSMesa, platform clash, ...
            errors.append(f"{backend}: {type(e).__name__}: {str(e)[:80]}")
    return None, "; ".join(errors) or "no OpenGL backend"


def _gl_context(backend: str, width: int, height: int) -> Any:
    if backend == "egl":
        from mujoco.egl import GLContext
    elif backend == "osmesa":
        from mujoco.osmesa import GLContext
    else:
        from mujoco.glfw import GLContext
    return GLContext(width, height)


def _render(episodes: dict[str, Episode], backend: str, width: int, height: int) -> np.ndarray:
    import mujoco

    from amex.cli import load_config
    from amex.episode import Simulation
    from amex.robot import load_robot
    from amex.scenario import make_scenario

    first = next(iter(episodes.values()))
    config = load_config([f"task={TASK}"])
    robot = load_robot(config.robot)
    scenario = make_scenario(config.scenario, TASK, SEED, ENV, first.tcp[0], 4.0)
    sim = Simulation(robot, scenario, 1000.0)
    model, data = sim.model, sim.data
    sim.set_obstacles(first.obstacles)
    for k in range(scenario.n_obstacles):
        model.geom_rgba[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"obstacle_{k}")] = (
            0.02,
            0.02,
            0.02,
            1.0,
        )
    for g in range(model.ngeom):  # a translucent arm keeps the paths behind it visible
        if model.geom_bodyid[g] and not model.body_mocapid[model.geom_bodyid[g]] >= 0:
            model.geom_rgba[g] = (0.75, 0.75, 0.78, 0.45)
    data.qpos[:] = first.q[-1]
    mujoco.mj_forward(model, data)
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    model.vis.headlight.ambient[:] = 0.45
    ctx = _gl_context(backend, width, height)
    ctx.make_current()
    try:
        scene = mujoco.MjvScene(model, maxgeom=20000)
        camera = mujoco.MjvCamera()
        points = np.concatenate([first.reference, first.goal, first.tcp])
        camera.lookat[:] = (points.min(axis=0) + points.max(axis=0)) / 2
        camera.distance, camera.azimuth, camera.elevation = CAMERA
        mujoco.mjv_updateScene(
            model, data, mujoco.MjvOption(), None, camera, mujoco.mjtCatBit.mjCAT_ALL, scene
        )
        _add_path(scene, first.reference, RENDER_RGBA["reference"], 0.004)
        for name, e in episodes.items():
            _add_path(scene, e.tcp, RENDER_RGBA.get(name, (0.6, 0.6, 0.6, 1.0)), 0.004)
        _add_path(scene, first.goal, RENDER_RGBA["goal"], 0.005)
        for p in (first.goal[0], first.goal[-1]):
            _add_sphere(scene, p, 0.015, RENDER_RGBA["goal"])
        _add_floor(scene)
        context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
        viewport = mujoco.MjrRect(0, 0, width, height)
        mujoco.mjr_render(viewport, scene, context)
        rgb = np.empty((height, width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(rgb, None, viewport, context)
        context.free()
    finally:
        ctx.free()
    return np.flipud(rgb)


def _add_path(scene: Any, points: np.ndarray, rgba: tuple, width: float) -> None:
    import mujoco

    step = max(1, len(points) // 150)
    pts = np.concatenate([points[::step], points[-1:]])
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        if scene.ngeom >= scene.maxgeom or np.allclose(a, b):
            continue
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(
            geom,
            mujoco.mjtGeom.mjGEOM_CAPSULE,
            np.zeros(3),
            np.zeros(3),
            np.eye(3).ravel(),
            np.asarray(rgba, dtype=np.float32),
        )
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, width, a, b)
        scene.ngeom += 1


def _add_floor(scene: Any, half: float = 0.8) -> None:
    """A light floor at z = 0 (the model has none) so dark objects stand out."""
    import mujoco

    if scene.ngeom < scene.maxgeom:
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            mujoco.mjtGeom.mjGEOM_BOX,
            np.array([half, half, 0.002]),
            np.array([0.3, 0.0, -0.002]),
            np.eye(3).ravel(),
            np.array([0.82, 0.82, 0.8, 1.0], dtype=np.float32),
        )
        scene.ngeom += 1


def _add_sphere(scene: Any, center: np.ndarray, radius: float, rgba: tuple) -> None:
    import mujoco

    if scene.ngeom < scene.maxgeom:
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            mujoco.mjtGeom.mjGEOM_SPHERE,
            np.full(3, radius),
            np.asarray(center, dtype=float),
            np.eye(3).ravel(),
            np.asarray(rgba, dtype=np.float32),
        )
        scene.ngeom += 1


if __name__ == "__main__":
    print(*plot_fig4(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("analysis/out")))
