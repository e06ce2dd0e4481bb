"""The paper's Fig. 4 on the Panda: one Task-3 scene with the executed paths of AMEX, DMP and CR.

Drawn from the episode logs of ``amex-run -m experiment=fig4`` (``conf/experiment/fig4.yaml``:
Task 3, environment 0, every method logged into ``runs/fig4/``), read with
:func:`amex.log.read_log`, so the figure shows exactly what ``amex-log`` shows. As in the paper:
a black obstacle, the goal in gold (a ring where it starts, a star where it ends), the reference
plan in red, each method's TCP path in its colour of :mod:`amex.core.palette`. Panels: (a) a
MuJoCo offscreen render (:mod:`amex.log.render`; if headless OpenGL works here, else it says
why), (b) a 3-D plot, (c, d) top and side views. Runs of another arm or scene
(``robot=chain7``) give their own figure: ``python -m analysis.fig4 [RUNS] [--out DIR]``.
"""

from __future__ import annotations

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

from . import default_out

TASK = 3
ENV = 0  # the Task-3 environment drawn (a goal the obstacle sits right in front of)
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


def logs_of(runs: Path) -> tuple[dict[str, Path], tuple[str, ...]]:
    """The first episode log of each run under ``runs`` by method, in the paper's order, and the
    overrides those runs share besides ``experiment`` and ``method`` (e.g. ``robot=chain7``).

    Raises:
        StudyError: no logged run there.
    """
    from .comparisons import method_rank
    from .sweep import StudyError, read_yaml

    found: dict[str, Path] = {}
    shared: set[str] | None = None
    for log in sorted(runs.glob(f"*/logs/episode_{ENV:03d}.mcap")):
        run = log.parent.parent
        config = read_yaml(run / ".hydra" / "config.yaml") or {}
        found[str(config.get("method", {}).get("name", run.name))] = log
        overrides = {str(o) for o in read_yaml(run / ".hydra" / "overrides.yaml") or []}
        shared = overrides if shared is None else shared & overrides
    if not found:
        raise StudyError(f"{runs}: no logged runs; run `amex-run -m experiment=fig4`")
    skip = ("experiment=", "method=", "hydra.")
    common = tuple(sorted(o for o in shared or () if not o.startswith(skip)))
    return {m: found[m] for m in sorted(found, key=method_rank)}, common


def plot_fig4(runs: Path | str, out_dir: Path | str) -> list[Path]:
    """Draw Fig. 4 from the logged runs under ``runs`` (``amex-run -m experiment=fig4``).

    Writes ``out_dir/fig4_task3.png`` (with a suffix for each override the runs share, e.g.
    ``fig4_task3_chain7.png``) and returns ``[its path]``.
    """
    logs, overrides = logs_of(Path(runs))
    return [plot_logs(logs, out_dir, overrides)]


def plot_logs(
    logs: Mapping[str, Path | str], out_dir: Path | str, overrides: tuple[str, ...] = ()
) -> Path:
    """Draw Fig. 4 from one environment's MCAP logs by method name; return the PNG's path."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    episodes = {name: episode_from_log(path) for name, path in logs.items()}
    image, why = render_scene(episodes)
    suffix = "".join(f"_{o.split('=', 1)[1]}" for o in overrides if "=" in o)
    return _draw(episodes, image, why, out_dir / f"fig4_task3{suffix.replace('/', '-')}.png")


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
        draw_caption,
        frame_points,
        gl_context,
        joint_addresses,
        split_viewport,
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
        arm = frame_points(model, addresses, np.asarray(first.q)[-1:])  # the whole arm shown
        points = np.concatenate([first.reference, first.goal, first.tcp, first.obstacles, arm])
        aim_camera(camera, points, first.goal[0] - first.tcp[0], margin=1.1)
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
            view, top, bottom = split_viewport(viewport, 40)  # the caption off the scene
            mujoco.mjr_render(view, scene, context)
            caption = f"arm: {method_label(first.method)}, t = {first.t[-1]:.2f} s"
            draw_caption(context, top, caption)
            draw_caption(context, bottom, "")
            rgb = np.empty((height, width, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(rgb, None, viewport, context)
        finally:
            context.free()
    finally:
        gl.free()
    return np.flipud(rgb)


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m analysis.fig4 [RUNS] [--out DIR]`` (RUNS: runs/fig4)."""
    from amex.app.argparsing import OneLineParser
    from amex.core.errors import AmexError

    from . import print_written

    parser = OneLineParser(prog="python -m analysis.fig4", description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="?", type=Path, default=Path("runs/fig4"))
    parser.add_argument("--out", type=Path, default=default_out())
    args = parser.parse_args(argv)
    return print_written(
        "python -m analysis.fig4", lambda: plot_fig4(args.runs, args.out), (AmexError,)
    )


if __name__ == "__main__":
    raise SystemExit(main())
