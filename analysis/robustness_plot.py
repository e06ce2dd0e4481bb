"""The robustness study's plots: success, final time and smoothness versus the swept variable."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from amex.core.palette import method_color, method_label

from .robustness_study import Study

#: Panels: (mean column, interval low, interval high); no interval for the smoothness.
PANELS = (
    ("success", "success_ci_low", "success_ci_high"),
    ("final_time_mean", "final_time_ci_low", "final_time_ci_high"),
    ("sum_sq_acc_mean", None, None),
)


def plot_sweep(study: Study, cells: pd.DataFrame, sweep: str, path: Path) -> Path:
    """Success and final time versus the swept variable; solid with, dashed without prediction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    key = "speed_factor" if sweep == "speed" else "noise_std"
    sub = cells[cells.sweep == sweep].sort_values(key)
    scale = 1.0 if sweep == "speed" else 1e3
    xlabel = "goal speed factor (x default std)" if sweep == "speed" else "goal noise std [mm]"
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    methods = list(dict.fromkeys(sub.method))
    xs = np.sort(sub[key].unique()) * scale
    width = 0.012 * (xs.max() - xs.min() if len(xs) > 1 else 1.0)
    for i, method in enumerate(methods):
        for pred in (False, True):
            g = sub[(sub.method == method) & (sub.prediction == pred)]
            x = g[key].to_numpy() * scale + (i - 1 + (0.5 if pred else -0.5) / 2) * width
            style = dict(
                color=method_color(method),
                linestyle="-" if pred else "--",
                marker="o" if pred else "s",
                markersize=4,
                capsize=2,
                label=f"{method_label(method)}, " + ("prediction" if pred else "raw"),
            )
            for ax, (mean, lo, hi) in zip(axes, PANELS, strict=True):
                m = g[mean].to_numpy()
                err = None
                if lo is not None:
                    err = np.clip(np.vstack([m - g[lo].to_numpy(), g[hi].to_numpy() - m]), 0, None)
                ax.errorbar(x, m, yerr=err, **style)
    low = float(np.nanmin(sub.success_ci_low)) if len(sub) else 0.0
    axes[0].set_ylim(max(0.0, min(low - 0.05, 0.8)), 1.02)
    axes[0].set_ylabel("success rate (0.03 m)")
    axes[1].set_ylabel("final time [s] (10 s = time limit)")
    axes[2].set_ylabel("sum of squared joint accelerations")
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xlabel(xlabel)
        ax.set_xticks(xs)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8, ncol=1, loc="best")
    noise = max((c.noise_std for c in study.cells("speed")), default=0.0) * 1e3
    what = f"goal speed ({noise:g} mm noise)" if sweep == "speed" else "goal noise (speed x 1)"
    n = int(sub.episodes.min()) if len(sub) else 0
    fig.suptitle(
        f"Task {study.task}, latency {study.latency * 1e3:g} ms: success, final time and "
        f"smoothness vs {what}; n = {n} paired environments, bars: unpaired 95 % CI of the mean"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
