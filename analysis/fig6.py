"""The paper's Fig. 6 in simulation, drawn from episode logs: reference versus executed TCP path.

The paper's Fig. 6 shows the PR2's hand in task space: the reference motion (red), the motion
AMEX executed while the tracked goal moved, and the goal positions as dots. Here the same from
one or more logged AMEX episodes (``log=full``; :func:`trace_of` reads one): top and side views
of the paths with the perceived goals as dots and the true goal's path, and below AMEX's phase
with the distance to the goal and Eq. 9's commanded versus the actual TCP speed over time.

``make figures`` draws it from the runs of ``amex-run experiment=fig6`` (``runs/fig6``: the
logged Task-2 environment whose goal moves farthest), :mod:`analysis.pr2` from the pr2_like
study's logged episodes. ``python -m analysis.fig6 [RUN_DIR] [--out DIR]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import default_out

COLORS = ("tab:blue", "tab:purple", "tab:orange")
DOT_EVERY = 0.05  # [s] at least between two drawn goal positions


@dataclass(frozen=True)
class Trace:
    """What Fig. 6 draws of one logged episode (all series at its outer steps).

    Attributes:
        label: its name in the legends.
        t: times [s], shape (n,).
        tcp: TCP positions, (n, 3) [m].
        speed: actual TCP speed, (n,) [m/s].
        speed_cmd: commanded TCP speed ``|y_dot*|``, (n,) [m/s].
        s: AMEX's phase, (n,) [-].
        seen: the goal as the method perceived it, (n, 3) [m].
        goal: the true goal, (n, 3) [m].
        reference: the reference plan's TCP path, (N + 1, 3) [m].
        outcome: the episode's result (``success``, ``final_distance``, ``final_time``).
    """

    label: str
    t: np.ndarray
    tcp: np.ndarray
    speed: np.ndarray
    speed_cmd: np.ndarray
    s: np.ndarray
    seen: np.ndarray
    goal: np.ndarray
    reference: np.ndarray
    outcome: dict[str, Any]


def trace_of(path: Path, label: str) -> Trace:
    """The :class:`Trace` of the episode logged at ``path`` (:func:`amex.log.read_log`)."""
    from amex.log import read_log
    from amex.log.video import scenario_of

    log = read_log(path)
    t = log.times("/tcp")
    n = len(t)
    scenario = scenario_of(log)
    return Trace(
        label=label,
        t=t,
        tcp=log.series("/tcp", "position").reshape(-1, 3),
        speed=np.linalg.norm(log.series("/tcp", "velocity").reshape(-1, 3), axis=1),
        speed_cmd=np.linalg.norm(log.series("/command", "yd_star")[:n, :3], axis=1),
        s=log.series("/method", "s")[:n],
        seen=log.series("/goal", "position").reshape(-1, 3)[:n],
        goal=np.array([scenario.goal_at(float(time)) for time in t]).reshape(-1, 3),
        reference=log.reference_path(),
        outcome=log.outcome or {},
    )


def _outcome(outcome: dict[str, Any]) -> str:
    if "success" not in outcome:
        return "no outcome"
    word = "success" if outcome["success"] else "fail"
    return f"{word}, {100 * outcome['final_distance']:.1f} cm at {outcome['final_time']:.1f} s"


def _paths(ax: Any, traces: Sequence[Trace], i: int, j: int, name: str) -> None:
    """One view of the reference, the executed paths, the perceived and the true goal."""
    import matplotlib.pyplot as plt

    first = traces[0]
    ref = first.reference
    ax.plot(ref[:, i], ref[:, j], color="tab:red", lw=2, label=r"reference $\tau_{ref}$")
    ax.plot(*ref[0, [i, j]], "ko", ms=6, label="start")
    dt = float(np.median(np.diff(first.t))) if len(first.t) > 1 else DOT_EVERY
    every = max(1, round(DOT_EVERY / dt))
    for k, tr in enumerate(traces):
        c = COLORS[k % len(COLORS)]
        if k == 0:
            seen = tr.seen[::every]
            rate = f"{1 / (every * dt):.3g} Hz"
            ax.scatter(seen[:, i], seen[:, j], s=9, color=c, alpha=0.35, lw=0,
                       label=f"perceived goal ({rate})")  # fmt: skip
        label = f"executed, {tr.label}\n({_outcome(tr.outcome)})"
        ax.plot(tr.tcp[:, i], tr.tcp[:, j], color=c, lw=1.8, ls="-" if k == 0 else "--",
                label=label)  # fmt: skip
    g = first.goal
    ax.plot(g[:, i], g[:, j], color="gold", lw=3, zorder=0, label="true goal path")
    ax.plot(*g[-1, [i, j]], marker="*", color="goldenrod", ms=14, ls="", label="final goal")
    ax.add_patch(plt.Circle(tuple(g[-1, [i, j]]), 0.03, fill=False, ls=":", color="goldenrod"))
    ax.set_xlabel("xyz"[i] + " [m]")
    ax.set_ylabel("xyz"[j] + " [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{name} (dotted circle: 3 cm success radius)")
    ax.grid(alpha=0.3)


def _over_time(ax_s: Any, ax_v: Any, traces: Sequence[Trace]) -> None:
    """Phase and distance to the goal (left), commanded and actual TCP speed (right)."""
    ax_d = ax_s.twinx()
    for k, tr in enumerate(traces):
        c, ls = COLORS[k % len(COLORS)], "-" if k == 0 else "--"
        ax_s.plot(tr.t, tr.s, color=c, ls=ls, lw=2, label=f"phase s, {tr.label}")
        dist = 100 * np.linalg.norm(tr.tcp - tr.goal, axis=1)
        ax_d.plot(tr.t, dist, color=c, ls=ls, lw=0.9, alpha=0.55)
        ax_s.plot([], [], color=c, ls=ls, lw=0.9, alpha=0.55, label=f"distance, {tr.label}")
        ax_v.plot(tr.t, 100 * tr.speed_cmd, color=c, ls=ls, lw=0.9, alpha=0.6,
                  label=f"commanded |y*'|, {tr.label}")  # fmt: skip
        ax_v.plot(tr.t, 100 * tr.speed, color=c, ls=ls, lw=1.8, label=f"actual |y'|, {tr.label}")
    ax_d.axhline(3.0, color="goldenrod", lw=0.8, ls=":")
    ax_d.set_ylabel("TCP distance to the true goal [cm] (thin; dotted: 3 cm)")
    ax_d.set_ylim(0, None)
    ax_s.set_ylim(0, 1.02)
    ax_s.set_xlabel("t [s]")
    ax_s.set_ylabel("phase s [-] (thick)")
    ax_s.set_title("AMEX phase and distance to the goal")
    ax_v.set_xlabel("t [s]")
    ax_v.set_ylabel("TCP speed [cm/s]")
    ax_v.set_title("Eq. 9 commanded speed versus actual speed")
    for ax in (ax_s, ax_v):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")


def plot_fig6(traces: Sequence[Trace], path: Path, title: str) -> Path:
    """Top and side views of the paths (top row), phase and speeds over time (bottom row)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 9))
    for ax, (i, j), name in zip(axes[0], ((0, 1), (0, 2)), ("top view", "side view"), strict=True):
        _paths(ax, traces, i, j, name)
    axes[0, 0].legend(fontsize=7, loc="upper left")
    _over_time(axes[1, 0], axes[1, 1], traces)
    fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def farthest_goal(run_dir: Path) -> Path:
    """The log in ``run_dir/logs`` of the environment whose goal moves farthest."""
    from .model import robot_of, scenario_of
    from .sweep import StudyError, read_yaml

    logs = sorted((run_dir / "logs").glob("episode_*.mcap"))
    if not logs:
        raise StudyError(f"{run_dir}: no episode logs; run `amex-run experiment=fig6`")
    config = read_yaml(run_dir / ".hydra" / "config.yaml")
    robot = robot_of(config)

    def travel(log: Path) -> float:
        s = scenario_of(config, robot, int(log.stem.removeprefix("episode_")))
        return float(np.linalg.norm(s.goal_at(s.goal_stop_time) - s.goal_start))

    return max(logs, key=travel)


def plot_run(run_dir: Path, out_dir: Path) -> list[Path]:
    """Fig. 6 of the run in ``run_dir`` (``amex-run experiment=fig6``) as ``fig6_task2.png``."""
    log = farthest_goal(run_dir)
    trace = trace_of(log, "AMEX")
    env = int(log.stem.removeprefix("episode_"))
    title = f"Fig. 6 analogue: Task 2 (moving goal), environment {env}, AMEX"
    return [plot_fig6([trace], out_dir / "fig6_task2.png", title)]


def main(argv: list[str] | None = None) -> int:
    """Command line (see the module docstring)."""
    from amex.app.argparsing import OneLineParser
    from amex.core.errors import AmexError

    from . import print_written

    parser = OneLineParser(prog="python -m analysis.fig6", description=__doc__.splitlines()[0])
    parser.add_argument("run", nargs="?", type=Path, default=Path("runs/fig6"))
    parser.add_argument("--out", type=Path, default=default_out())
    args = parser.parse_args(argv)
    return print_written(
        "python -m analysis.fig6", lambda: plot_run(args.run, args.out), (AmexError,)
    )


if __name__ == "__main__":
    raise SystemExit(main())
