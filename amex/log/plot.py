"""The figure of one logged episode (``amex-log plot``).

Paths in task space, the distance to the goal, the method's internals, the joint accelerations.
Colours are the palette's (:mod:`amex.core.palette`): the method's own curves (its executed path,
its distance to the goal, its internals and joint accelerations) in its colour and shades of it,
the goal gold, the obstacle black, the reference red, annotations (success radius, start) grey.
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

from amex.core.palette import (
    GOAL_COLOR,
    NEUTRAL_COLOR,
    OBSTACLE_COLOR,
    REFERENCE_COLOR,
    method_color,
    method_label,
    method_shades,
)
from amex.log.files import write_new
from amex.log.plot3d import set_equal_axes_3d
from amex.log.reader import LogData


def plot_episode(data: LogData, output: Path) -> None:
    """Save the episode's figure (2 x 2 panels) as the new file ``output`` (format: its suffix).

    Rendered in memory and written whole (:func:`amex.core.durable.create_new`): an existing
    file is never replaced, and a full disk leaves no partial image under the name.

    Raises:
        LogExistsError: ``output`` exists; WriteError: it could not be written.
    """
    import matplotlib.pyplot as plt

    fig = episode_figure(data)
    image = io.BytesIO()
    fig.savefig(image, dpi=110, format=output.suffix.lstrip(".").lower())
    plt.close(fig)
    write_new(output, image.getvalue())


def episode_figure(data: LogData) -> Any:
    """The episode's figure (2 x 2 panels, matplotlib's Agg backend); close it when done."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    method = method_of(data)
    fig = plt.figure(figsize=(12, 8.5), layout="constrained")
    ax3 = fig.add_subplot(2, 2, 1, projection="3d")
    draw_paths(ax3, data)
    t = data.times("/goal")
    ax = fig.add_subplot(2, 2, 2)
    ax.plot(t, data.series("/goal", "distance"), color=method_color(method), gid="method")
    radius = "success radius 0.03 m"
    ax.axhline(0.03, color=NEUTRAL_COLOR, ls="--", lw=1, label=radius, gid="neutral")
    ax.set(xlabel="t [s]", ylabel="distance TCP - goal [m]", title="Distance to goal")
    ax.legend(loc="upper right")
    ax = fig.add_subplot(2, 2, 3)
    phase_keys = [k for k in ("s", "phase", "phase_rate", "index") if _has(data, "/method", k)]
    title = "Method internals: phase (AMEX s, DMP x)"
    scaled = not phase_keys  # no phase: every number, each divided by its largest magnitude
    if scaled:
        phase_keys = [k for k in _scalar_keys(data, "/method") if k != "t"]
        title = "Method internals, each divided by its largest |value|"
    for key, shade in zip(phase_keys, method_shades(method, len(phase_keys)), strict=True):
        values = data.series("/method", key)
        peak = float(np.nanmax(np.abs(values))) if scaled and np.isfinite(values).any() else 1.0
        label = f"{key} / {peak:.3g}" if scaled else key
        ax.plot(data.times("/method"), values / (peak or 1.0), label=label, color=shade,
                gid="method")  # fmt: skip
    ax.set(xlabel="t [s]", title=title)
    if phase_keys:
        ax.legend(loc="best")
    else:
        ax.text(0.5, 0.5, "no numeric internals logged", ha="center", transform=ax.transAxes)
    ax = fig.add_subplot(2, 2, 4)
    qdd = data.joints("acceleration")
    if qdd.size:
        shades = method_shades(method, qdd.shape[1])
        for j in range(qdd.shape[1]):
            ax.plot(data.times("/joint_states"), qdd[:, j], lw=1, label=f"joint {j + 1}",
                    color=shades[j], gid="method")  # fmt: skip
        ax.legend(loc="upper right", ncol=2, fontsize="small")
    ax.set(xlabel="t [s]", ylabel="q_ddot [rad/s^2]", title="Joint accelerations (100 Hz)")
    fig.suptitle(_title(data))
    return fig


def method_of(data: LogData) -> str:
    """The logged episode's method (its ``episode`` metadata), or ""."""
    return str(data.metadata.get("episode", {}).get("method", ""))


def _title(data: LogData) -> str:
    episode = data.metadata.get("episode", {})
    name = " ".join(f"{k}={episode[k]}" for k in ("task", "method", "env", "seed") if k in episode)
    outcome = data.outcome or {}
    tail = ""
    if "success" in outcome:
        tail = (
            f" - {'success' if outcome['success'] else 'no success'}, final distance "
            f"{outcome.get('final_distance', math.nan):.3f} m at "
            f"{outcome.get('final_time', math.nan):.2f} s"
        )
    if data.damage:
        tail += f" (recovered from a {data.damage} file)"
    return (name or str(data.path.name)) + tail


def _has(data: LogData, topic: str, key: str) -> bool:
    return any(isinstance(m.data, dict) and key in m.data for m in data.messages.get(topic, []))


def _scalar_keys(data: LogData, topic: str) -> list[str]:
    keys: dict[str, None] = {}
    for m in data.messages.get(topic, []):
        if isinstance(m.data, dict):
            for k, v in m.data.items():
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    keys[k] = None
    return list(keys)


def draw_paths(ax: Any, data: LogData) -> None:
    """On 3-D axes: reference plan, executed TCP path, goal path and obstacle spheres."""
    import numpy as np

    ref = data.reference_path()
    tcp = data.series("/tcp", "position")
    goal = data.series("/goal", "position")
    method = method_of(data)
    if len(ref):
        ax.plot(*ref.T, color=REFERENCE_COLOR, ls="--", lw=1.5, label="reference plan",
                gid="reference")  # fmt: skip
    ax.plot(*tcp.T, color=method_color(method), lw=2, gid="method",
            label=f"executed TCP path ({method_label(method)})")  # fmt: skip
    ax.plot(*goal.T, color=GOAL_COLOR, lw=2, label="goal path", gid="goal")
    ax.scatter(*goal[-1], color=GOAL_COLOR, s=40, marker="o", label="goal (end)", gid="goal")
    ax.scatter(*tcp[0], color=NEUTRAL_COLOR, s=25, marker="s", label="start", gid="neutral")
    scenario = data.metadata.get("scenario", {})
    centers = np.asarray(scenario.get("obstacle_start") or np.zeros((0, 3)), dtype=float)
    radii = np.asarray(scenario.get("obstacle_radii") or [], dtype=float)
    u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
    for c, r in zip(centers.reshape(-1, 3), radii, strict=False):
        ax.plot_surface(
            c[0] + r * np.cos(u) * np.sin(v),
            c[1] + r * np.sin(u) * np.sin(v),
            c[2] + r * np.cos(v),
            color=OBSTACLE_COLOR,
            alpha=0.3,
            linewidth=0,
            shade=False,  # the palette's black, not a lit variant of it
            gid="obstacle",
        )
    if len(radii):
        ax.plot([], [], color=OBSTACLE_COLOR, lw=6, alpha=0.4, label="obstacle", gid="obstacle")
    points = np.concatenate([p for p in (ref, tcp, goal) if len(p)])
    set_equal_axes_3d(ax, points, pad=1.1, min_half=0.05)
    ax.legend(loc="center left", bbox_to_anchor=(1.2, 0.5), fontsize="small")
    ax.set_title("TCP and goal in task space")
