"""The paper's Fig. 2, drawn by the AMEX class itself: 2-D plans and phase s(t), perfect execution.

(a) the goal offset before the start, (b) the goal moving during the first 70 % of T_ref; with a
constant-speed reference (``fig2_amex.png``) and a rest-to-rest one
(``fig2_amex_rest_to_rest.png``). The robot reaches every command exactly (``y <- y*``), so the
paths are the adapted plans; a run ends within 1e-3 of the goal in the final approach. What the
two versions show: ``docs/analysis.md``. Run ``python analysis/fig2.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from amex.methods.amex import AMEX
from amex.plan.reference import ReferencePlan

from . import default_out

T_REF = 4.0  # [s]
DT = 0.01  # [s], Delta s_ref = 0.0025 like the original
T_MAX = 10.0  # [s], the original's episode limit
COLORS = ("tab:blue", "tab:green", "black")


def reference_2d(n_samples: int = 401, rest_to_rest: bool = False) -> np.ndarray:
    """A half-ellipse from (0, 0) to (1, 0): constant speed, or minimum-jerk timing; (n, 2)."""
    p = np.linspace(0.0, 1.0, n_samples)
    u = 10 * p**3 - 15 * p**4 + 6 * p**5 if rest_to_rest else p
    return np.stack([0.5 - 0.5 * np.cos(np.pi * u), 0.6 * np.sin(np.pi * u)], axis=1)


def execute(amex: AMEX, goal_at, y0: np.ndarray, tol: float = 1e-3):
    """Run AMEX with perfect execution; return times, states y (before each step), goals, s."""
    amex.restart()
    y = np.array(y0, dtype=float)
    ts, ys, gs, ss = [], [], [], []
    for k in range(int(T_MAX / DT) + 1):
        g = goal_at(k * DT)
        target = amex.update(y, g)
        ts.append(k * DT)
        ys.append(y.copy())
        gs.append(g.copy())
        ss.append(target.s)
        if amex.final_approach and np.linalg.norm(g - y) < tol:
            break
        y = target.y_star
    return np.array(ts), np.array(ys), np.array(gs), np.array(ss)


def plot_fig2(out_dir: Path) -> list[Path]:
    """Draw Fig. 2 (a) and (b) into ``out_dir``, both references; return the PNG paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [
        _draw(plt, reference_2d(), out_dir / "fig2_amex.png", "constant-speed"),
        _draw(plt, reference_2d(rest_to_rest=True), out_dir / "fig2_amex_rest_to_rest.png",
              "rest-to-rest (minimum-jerk)"),
    ]  # fmt: skip


def _draw(plt, Y: np.ndarray, path: Path, label: str) -> Path:
    amex = AMEX(ReferencePlan.from_path(Y, T_REF), dt=DT)
    g_ref = Y[-1]
    offsets = [np.array([0.25, 0.45]), np.array([0.45, -0.25]), np.array([-0.35, -0.2])]
    velocities = [np.array([0.08, 0.10]), np.array([0.12, -0.06])]

    def fixed(off):
        return lambda t: g_ref + off

    def moving(vel):
        return lambda t: g_ref + vel * min(t, 0.7 * T_REF)

    def towards_then_away(t):  # plan 3: first towards the robot's start, then away
        turn = 0.35 * T_REF
        a = np.array([-0.15, 0.05])
        return g_ref + a * min(t, turn) - a * 1.6 * max(0.0, min(t, 0.7 * T_REF) - turn)

    panels = {
        "a": ("goal offset before the start", [fixed(o) for o in offsets]),
        "b": ("goal moving during execution", [*map(moving, velocities), towards_then_away]),
    }
    fig, axes = plt.subplots(
        2, 2, figsize=(13, 7.5), gridspec_kw={"height_ratios": [2.2, 1]}, constrained_layout=True
    )
    for col, (key, (title, goals)) in enumerate(panels.items()):
        top, bottom = axes[0, col], axes[1, col]
        top.plot(Y[:, 0], Y[:, 1], color="red", lw=2.5, label=r"$\tau^{ref}$")
        bottom.plot([0, T_REF], [0, 1], color="red", lw=2.5, label=r"reference $s = t/T^{ref}$")
        for i, goal_at in enumerate(goals):
            c = COLORS[i]
            t, y, g, s = execute(amex, goal_at, Y[0])
            top.plot(y[:, 0], y[:, 1], color=c, lw=1.8, label=f"adapted plan {i + 1}")
            if key == "b":
                top.plot(g[::10, 0], g[::10, 1], ".", color=c, ms=4)
            top.plot(*g[-1], "o", mfc="none", mec=c, ms=12, mew=2)
            bottom.plot(t, s, color=c, lw=1.8, label=f"plan {i + 1}")
        top.plot(*g_ref, "o", mfc="none", mec="red", ms=12, mew=2)
        top.plot(*Y[0], "ks", ms=6, label="start")
        top.set(title=f"({key}) {title}", xlabel="$y_1$", ylabel="$y_2$", aspect="equal")
        top.grid(alpha=0.3)
        top.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
        bottom.set(xlabel="time t [s]", ylabel="phase s", ylim=(0, 1.05))
        bottom.grid(alpha=0.3)
        bottom.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.suptitle(
        f"AMEX (Eq. 7-9), {label} reference, perfect execution: circles = goals, dots = goal motion"
    )
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


if __name__ == "__main__":
    for p in plot_fig2(default_out()):
        print(p)
