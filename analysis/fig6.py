"""The paper's Fig. 6 in simulation: reference versus executed TCP path, goal positions as dots.

The paper's Fig. 6 shows the PR2's hand in task space: the reference motion (red), the motion
AMEX executed while the tracked goal moved (blue), and the goal positions (blue dots). Here the
same for one Task-2 episode (the goal starts at the reference goal and moves during the first
70 % of T_ref) on the simulated Panda: AMEX if it is registered, else DMP. The environment is the
one, among the first :data:`CANDIDATES`, whose goal moves farthest (the clearest adaptation).
The episode is logged to MCAP in a temporary directory and read back with
:func:`amex.log.read_log`. Run ``python analysis/fig6.py [OUT_DIR]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

TASK = 2
SEED = 0
CANDIDATES = 10  # environments searched for the largest goal motion
GOAL_DOT_EVERY = 0.1  # [s] between drawn goal positions


def pick_method() -> str:
    """AMEX if registered, else DMP."""
    from amex.methods import METHODS

    return "amex" if "amex" in METHODS else "dmp"


def pick_env(config, start_tcp: np.ndarray, duration: float) -> int:
    """The environment (of the first CANDIDATES) whose goal moves farthest."""
    from amex.sim.scenario import make_scenario

    def travel(env: int) -> float:
        s = make_scenario(config.scenario, TASK, SEED, env, start_tcp, duration)
        return float(np.linalg.norm(s.goal_at(s.goal_stop_time) - s.goal_start))

    return max(range(CANDIDATES), key=travel)


def plot_fig6(out_dir: Path | str) -> list[Path]:
    """Run the Task-2 episode, draw ``out_dir/fig6_task2.png``; return ``[its path]``."""
    from amex.app.cli import load_config
    from amex.experiment.runner import prepare, run_one
    from amex.log import read_log

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    method = pick_method()
    config = load_config([f"task={TASK}", f"method={method}", f"seed={SEED}"])
    context = prepare(config)
    env = pick_env(config, context.plan.y[0, :3], context.plan.duration)
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "episode.mcap"
        run_one(config, context, env, log)
        data = read_log(log)
    t = data.times("/tcp")
    tcp = data.series("/tcp", "position")
    goal = data.series("/goal", "position")
    reference = data.reference_path()
    every = max(1, round(GOAL_DOT_EVERY / float(np.median(np.diff(t)))))
    reference_dt = float(data.messages["/reference"][0].data["dt"])
    figure = _draw(
        out_dir / "fig6_task2.png",
        method,
        env,
        reference,
        reference_dt,
        t,
        tcp,
        t[::every],
        goal[::every],
        data.outcome or {},
    )
    return [figure]


def _draw(
    path: Path,
    method: str,
    env: int,
    reference,
    reference_dt: float,
    t,
    tcp,
    t_dots,
    dots,
    outcome: dict,
) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    name = {"amex": "AMEX", "dmp": "DMP"}.get(method, method)
    fig = plt.figure(figsize=(15, 5.6), layout="constrained")
    grid = fig.add_gridspec(3, 3, width_ratios=(1.1, 1, 1))
    t_ref = np.arange(len(reference)) * reference_dt
    for i in range(3):
        ax = fig.add_subplot(grid[i, 0])
        ax.plot(t_ref, reference[:, i], color="tab:red", lw=2)
        ax.plot(t, tcp[:, i], color="tab:blue", lw=2)
        ax.scatter(t_dots, dots[:, i], color="tab:blue", s=10)
        ax.set_ylabel("xyz"[i] + " [m]")
        ax.grid(alpha=0.3)
        if i == 0:
            ax.set_title("(a) TCP position over time")
        if i < 2:
            ax.tick_params(labelbottom=False)
    ax.set_xlabel("t [s]")
    for k, (i, j, title) in enumerate(
        [(0, 1, "(b) top view (x-y)"), (0, 2, "(c) side view (x-z)")]
    ):
        ax = fig.add_subplot(grid[:, k + 1])
        ax.plot(
            reference[:, i], reference[:, j], color="tab:red", lw=2, label=r"reference $\tau^{ref}$"
        )
        ax.plot(tcp[:, i], tcp[:, j], color="tab:blue", lw=2, label=f"executed ({name})")
        ax.scatter(dots[:, i], dots[:, j], color="tab:blue", s=14, label="goal positions (10 Hz)")
        ax.scatter(tcp[0, i], tcp[0, j], color="k", marker="s", s=30, zorder=5, label="start")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set(xlabel="xyz"[i] + " [m]", ylabel="xyz"[j] + " [m]", title=title)
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(loc="best", fontsize="small")
    verdict = ""
    if "success" in outcome:
        verdict = (
            f"; {'reached' if outcome['success'] else 'missed'} the goal: final distance "
            f"{outcome['final_distance']:.3f} m at {outcome['final_time']:.2f} s"
        )
    fig.suptitle(f"Fig. 6 analogue: Task 2 (moving goal), environment {env}, {name}{verdict}")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    print(*plot_fig6(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "out"))
