"""The paper's Fig. 4 on the Panda: one Task-3 scene with the executed paths of AMEX, DMP and CR.

As in the paper: the obstacle is a black ball, the goal is gold (a ring where it starts, a star
where it ends, its path between), the reference plan (planned without the obstacle) is red; each
method's executed TCP path has its colour of :mod:`amex.core.palette` (AMEX blue, DMP green, CR
purple), the same in every panel, the render included. A moving obstacle (Task 4) is drawn with its
path. Each episode is run here and logged to MCAP in a temporary directory, then read back with
:func:`amex.log.read_log` (or read from the logs given), so the figure shows exactly what
``amex-log`` shows.

Two views: (a) a MuJoCo offscreen render of the scene (:mod:`amex.log.render`: the arm as the
log's URDF describes it, at the end of the first method's episode), if headless OpenGL works here
(otherwise (a) says why it is missing); (b) a labelled 3-D plot, with top and side projections
below. Run ``python -m analysis.fig4 [OUT_DIR] [OVERRIDES]``, e.g. ``robot=chain7`` or
``experiment=original``: the arm, the scene and the camera (aimed at the paths) follow them.
"""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from amex.core.palette import (
    GOAL_COLOR,
    OBSTACLE_COLOR,
    REFERENCE_COLOR,
    method_color,
    method_label,
    rgba,
)
from amex.log.plot3d import set_equal_axes_3d

TASK = 3
ENV = 0  # the Task-3 environment drawn (a goal the obstacle sits right in front of)
SEED = 0
FIG4_METHODS = ("amex", "dmp", "cr")
GOAL_START = {"marker": "o", "facecolor": "white", "edgecolor": GOAL_COLOR, "linewidths": 2.5}
GOAL_END = {"marker": "*", "color": GOAL_COLOR, "edgecolor": "k", "linewidths": 0.6}


@dataclass(frozen=True)
class Episode:
    """What a figure needs from one logged episode."""

    method: str
    t: np.ndarray  # (n,) [s]
    tcp: np.ndarray  # (n, 3) [m]
    goal: np.ndarray  # (n, 3) [m]
    q: np.ndarray  # (n, joints) [rad]
    reference: np.ndarray  # (N + 1, 3) [m]
    obstacles: np.ndarray  # (k, 3) [m] at the end of the episode
    obstacle_paths: np.ndarray  # (k, n, 3) [m] over the episode
    radii: np.ndarray  # (k,) [m]
    outcome: dict[str, Any]
    urdf_path: str
    package_dirs: list[str]
    joint_names: list[str]


def episode_from_log(path: Path | str) -> Episode:
    """Read the arrays of an episode log (see :mod:`amex.log.writer`)."""
    from amex.log import read_log
    from amex.log.video import scenario_of

    data = read_log(path)
    scenario = scenario_of(data)
    episode = data.metadata.get("episode", {})
    robot = data.metadata.get("robot", {})
    t = data.times("/tcp")
    paths = np.stack([scenario.obstacles_at(ti) for ti in t], axis=1) if len(t) else np.zeros(0)
    return Episode(
        method=str(episode.get("method", "?")),
        t=t,
        tcp=data.series("/tcp", "position"),
        goal=data.series("/goal", "position"),
        q=data.joints("position"),
        reference=data.reference_path(),
        obstacles=scenario.obstacles_at(float(t[-1]) if len(t) else 0.0),
        obstacle_paths=paths.reshape(scenario.n_obstacles, len(t), 3),
        radii=scenario.obstacle_radii,
        outcome=data.outcome or {},
        urdf_path=str(robot.get("urdf_path", "")),
        package_dirs=[str(d) for d in robot.get("package_dirs") or []],
        joint_names=[str(j) for j in robot.get("joint_names", [])],
    )


def run_logged(
    task: int,
    env: int,
    methods: list[str],
    out_dir: Path,
    seed: int = SEED,
    overrides: tuple[str, ...] = (),
) -> dict:
    """Run environment ``env`` of ``task`` with each method, logged into ``out_dir``; read back.

    ``overrides`` are command-line overrides of every run (``robot=chain7``,
    ``experiment=original``): the figure follows the robot and the scene they choose.
    """
    from amex.app.cli import load_config
    from amex.experiment.runner import prepare, run_one

    episodes = {}
    for name in methods:
        config = load_config([f"task={task}", f"method={name}", f"seed={seed}", *overrides])
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
    out_dir: Path | str,
    runs_or_none: Mapping[str, Path | str] | None = None,
    overrides: tuple[str, ...] = (),
) -> list[Path]:
    """Draw Fig. 4 into ``out_dir/fig4_task3.png``; return ``[its path]`` (like ``plot_fig2``).

    Args:
        out_dir: where the PNG goes.
        runs_or_none: MCAP logs of one environment by method name (e.g. from
            ``amex-run task=3 method=amex episodes=1 log=full``); None runs environment
            :data:`ENV` of Task 3 with every registered method among AMEX, DMP and CR.
        overrides: command-line overrides of those runs (e.g. ``robot=chain7``).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if runs_or_none:
        episodes = {name: episode_from_log(path) for name, path in runs_or_none.items()}
    else:
        with tempfile.TemporaryDirectory() as tmp:
            episodes = run_logged(TASK, ENV, available_methods(), Path(tmp), overrides=overrides)
    image, why = render_scene(episodes)
    suffix = "".join(f"_{o.split('=', 1)[1]}" for o in overrides if "=" in o)
    return [_draw(episodes, image, why, out_dir / f"fig4_task3{suffix.replace('/', '-')}.png")]


def _draw(episodes: dict[str, Episode], image: np.ndarray | None, why: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    first = next(iter(episodes.values()))
    fig = plt.figure(figsize=(13, 10.5), layout="constrained")
    grid = fig.add_gridspec(2, 2, height_ratios=(1.25, 1))
    ax = fig.add_subplot(grid[0, 0])
    if image is not None:
        ax.imshow(image)
        handles = [Line2D([], [], color=REFERENCE_COLOR, lw=3, label="reference plan")]
        handles += [
            Line2D([], [], color=method_color(m), lw=3, label=method_label(m)) for m in episodes
        ]
        handles += [
            Line2D([], [], color=GOAL_COLOR, lw=3, label="goal path"),
            Line2D([], [], color=GOAL_COLOR, marker="o", mfc="white", ls="", ms=6,
                   label="goal start (white dot)"),
            Line2D([], [], color=GOAL_COLOR, marker="o", ls="", ms=9, label="goal end"),
            Line2D([], [], color=OBSTACLE_COLOR, marker="o", ls="", ms=10, label="obstacle"),
        ]  # fmt: skip
        ax.legend(handles=handles, loc="lower left", fontsize="small", framealpha=0.85)
        ax.set_title(
            f"(a) MuJoCo render: the arm at the end of the {method_label(first.method)} episode"
        )
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
    lines = [f"{method_label(m)}: " + _outcome_text(e.outcome) for m, e in episodes.items()]
    fig.suptitle(
        f"Fig. 4 analogue: Task {TASK}, environment {ENV}; reference plan (red, planned without "
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


def _moving(first: Episode) -> list[np.ndarray]:
    """The paths of the obstacles that move (each (n, 3))."""
    return [p for p in first.obstacle_paths if len(p) and np.ptp(p, axis=0).max() > 1e-6]


def _paths_3d(ax: Any, episodes: dict[str, Episode], first: Episode) -> None:
    ax.plot(*first.reference.T, color=REFERENCE_COLOR, lw=2, label="reference plan")
    for name, e in episodes.items():
        ax.plot(*e.tcp.T, color=method_color(name), lw=2, label=method_label(name))
    goal = first.goal
    ax.plot(*goal.T, color=GOAL_COLOR, lw=3, label="goal path")
    ax.scatter(*goal[0], s=90, depthshade=False, label="goal start", **GOAL_START)
    ax.scatter(*goal[-1], s=220, depthshade=False, label="goal end", **GOAL_END)
    for c, r in zip(first.obstacles, first.radii, strict=False):
        _sphere(ax, c, r, OBSTACLE_COLOR, 0.45)
    for p in _moving(first):
        ax.plot(*p.T, color=OBSTACLE_COLOR, lw=1, ls="--", label="obstacle path")
    ax.plot([], [], color=OBSTACLE_COLOR, lw=8, alpha=0.5, label="obstacle")
    ax.scatter(*first.tcp[0], color="k", marker="s", s=30, depthshade=False, label="start")
    points = np.concatenate([first.reference, goal, *(e.tcp for e in episodes.values())])
    set_equal_axes_3d(ax, points, pad=1.05)
    ax.view_init(elev=25, azim=-125)
    ax.set_xlabel("x [m]", labelpad=8)
    ax.set_ylabel("y [m]", labelpad=8)
    ax.zaxis.set_rotate_label(False)  # upright, readable
    ax.set_zlabel("z [m]", labelpad=10, rotation=90)
    ax.set_box_aspect(None, zoom=0.85)  # room for the z label
    ax.set_title("(b) task space, 3-D (legend in (c))")


def _paths_2d(ax: Any, episodes: dict[str, Episode], first: Episode, i: int, j: int) -> None:
    from matplotlib.patches import Circle

    ax.plot(
        first.reference[:, i],
        first.reference[:, j],
        color=REFERENCE_COLOR,
        lw=2,
        label="reference plan",
    )
    for name, e in episodes.items():
        ax.plot(e.tcp[:, i], e.tcp[:, j], color=method_color(name), lw=2, label=method_label(name))
    goal = first.goal
    ax.plot(goal[:, i], goal[:, j], color=GOAL_COLOR, lw=3, label="goal path")
    ax.scatter(goal[0, i], goal[0, j], s=90, zorder=5, label="goal start", **GOAL_START)
    ax.scatter(goal[-1, i], goal[-1, j], s=220, zorder=6, label="goal end", **GOAL_END)
    for c, r in zip(first.obstacles, first.radii, strict=False):
        ax.add_patch(Circle((c[i], c[j]), r, color=OBSTACLE_COLOR, alpha=0.4, label="obstacle"))
    for p in _moving(first):
        ax.plot(p[:, i], p[:, j], color=OBSTACLE_COLOR, lw=1, ls="--", label="obstacle path")
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
    from amex.log.render import RenderError

    try:
        return _render(episodes, width, height), ""
    except RenderError as e:
        return None, str(e)


def _render(episodes: dict[str, Episode], width: int, height: int) -> np.ndarray:
    import mujoco

    from amex.log.render import (
        SceneDrawer,
        aim_camera,
        arm_model,
        gl_context,
        joint_addresses,
    )

    first = next(iter(episodes.values()))
    model = arm_model(first.urdf_path, 4, 0.45, first.package_dirs)
    model.vis.global_.offwidth, model.vis.global_.offheight = width, height
    data = mujoco.MjData(model)
    addresses = joint_addresses(model, first.joint_names)
    valid = addresses >= 0
    data.qpos[addresses[valid]] = first.q[-1][valid]
    mujoco.mj_forward(model, data)
    gl = gl_context(width, height)
    try:
        scene = mujoco.MjvScene(model, maxgeom=20000)
        camera = mujoco.MjvCamera()
        points = np.concatenate([first.reference, first.goal, first.tcp, first.obstacles])
        aim_camera(camera, points, first.goal[0] - first.tcp[0], margin=1.9)
        mujoco.mjv_updateScene(
            model, data, mujoco.MjvOption(), None, camera, mujoco.mjtCatBit.mjCAT_ALL, scene
        )
        draw = SceneDrawer(scene)
        draw.floor(np.asarray(camera.lookat[:2]), 4.0)
        draw.path(first.reference, rgba(REFERENCE_COLOR), 4.0)
        for name, e in episodes.items():
            draw.path(e.tcp, rgba(method_color(name)), 5.0)
        draw.path(first.goal, rgba(GOAL_COLOR), 5.0)
        draw.sphere(first.goal[0], 0.008, (1.0, 1.0, 1.0, 1.0))
        draw.sphere(first.goal[-1], 0.015, rgba(GOAL_COLOR))
        for c, r in zip(first.obstacles, first.radii, strict=False):
            draw.sphere(c, float(r), rgba(OBSTACLE_COLOR))
        for p in _moving(first):
            draw.path(p, rgba(OBSTACLE_COLOR, 0.7), 2.0)
        context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        try:
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
            viewport = mujoco.MjrRect(0, 0, width, height)
            mujoco.mjr_render(viewport, scene, context)
            mujoco.mjr_overlay(
                mujoco.mjtFont.mjFONT_BIG,
                mujoco.mjtGridPos.mjGRID_TOPLEFT,
                viewport,
                f"arm: {method_label(first.method)}, t = {first.t[-1]:.2f} s",
                "",
                context,
            )
            rgb = np.empty((height, width, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(rgb, None, viewport, context)
        finally:
            context.free()
    finally:
        gl.free()
    return np.flipud(rgb)


if __name__ == "__main__":  # python -m analysis.fig4 [OUT_DIR] [overrides, e.g. robot=chain7]
    given = sys.argv[1:]
    out = Path(given.pop(0)) if given and "=" not in given[0] else Path(__file__).parent / "out"
    print(*plot_fig4(out, overrides=tuple(given)))
