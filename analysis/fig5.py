"""The paper's Fig. 5 as figures: per task, the distributions behind the table's means.

One row per task: success at 0.03 m with 95 % Wilson intervals, and box plots of final time,
sum of squared accelerations and compute time with every environment as a dot, paired across
methods, the paper's means marked (details: ``docs/analysis.md``). Written as ``fig5.png`` and
``fig5.pdf`` (all tasks) and ``fig5_task<k>`` (one task each), one set per benchmark
configuration (``scene_<hash>/`` as ``make table`` does).

Run ``python -m analysis.fig5 [RUNS_DIR] [--out DIR]`` or ``make figures``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from amex.core.palette import method_color, method_label

from . import default_out

PANELS = (
    ("success", "success at 0.03 m", None),
    ("final_time", "final time [s]", "linear"),
    ("sum_sq_acc", "sum sq. acc. [rad²/s⁴]", "log"),
    ("compute_time_mean", "compute per step [s]", "log"),
)
PAIRED_PANELS = ("final_time", "sum_sq_acc")
PAPER_COLUMNS = {
    "success": "success",
    "final_time": "final_time_mean",
    "sum_sq_acc": "sum_sq_acc_mean",
    "compute_time_mean": "compute_time_mean",
}


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate (``z`` = 1.96); (nan, nan) for n = 0."""
    if n == 0:
        return math.nan, math.nan
    p = successes / n
    denominator = 1 + z**2 / n
    center = (p + z**2 / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / denominator
    return max(center - half, 0.0), min(center + half, 1.0)


def _paper_value(paper: pd.DataFrame, task: int, method: str, column: str) -> float:
    row = paper[(paper.task == task) & (paper.method == method)]
    return float(row[column].iloc[0]) if len(row) else math.nan


def _success(ax: Any, sub: pd.DataFrame, methods: list[str], paper: pd.DataFrame, task: int):
    for x, method in enumerate(methods):
        values = sub[sub.method == method].success.to_numpy(dtype=bool)
        rate = values.mean() if len(values) else math.nan
        lo, hi = wilson(int(values.sum()), len(values))
        ax.bar(x, rate, color=method_color(method), alpha=0.75, width=0.6)
        err = [[max(rate - lo, 0.0)], [max(hi - rate, 0.0)]]
        ax.errorbar(x, rate, yerr=err, color="k", capsize=4, lw=1.2)
        ax.text(x, 0.03, f"n={len(values)}", ha="center", va="bottom", fontsize="x-small")
        ax.plot(x, _paper_value(paper, task, method, "success"), "kD", ms=6, mfc="none")
    ax.set_ylim(0, 1.05)


def _distribution(
    ax: Any, sub: pd.DataFrame, methods: list[str], column: str, scale: str, paired: bool
) -> None:
    data = [sub[sub.method == m][column].to_numpy(dtype=float) for m in methods]
    data = [d[np.isfinite(d) & ((d > 0) if scale == "log" else True)] for d in data]
    if paired and len(methods) > 1:
        wide = sub.pivot_table(index="env", columns="method", values=column).reindex(
            columns=methods
        )
        for row in wide.to_numpy(dtype=float):
            ax.plot(range(len(methods)), row, color="0.5", alpha=0.12, lw=0.6, zorder=1)
    boxes = ax.boxplot(
        [d if len(d) else [np.nan] for d in data],
        positions=range(len(methods)),
        widths=0.5,
        showfliers=False,
        patch_artist=True,
        medianprops={"color": "k"},
        zorder=2,
    )
    rng = np.random.default_rng(0)
    for x, (method, d, box) in enumerate(zip(methods, data, boxes["boxes"], strict=True)):
        box.set(facecolor=method_color(method), alpha=0.35)
        jitter = rng.uniform(-0.15, 0.15, len(d))
        ax.scatter(x + jitter, d, s=7, color=method_color(method), alpha=0.7, zorder=3, lw=0)
    if scale == "log":
        ax.set_yscale("log")


def _row(axes: Any, sub: pd.DataFrame, paper: pd.DataFrame, task: int) -> None:
    from .comparisons import method_rank

    methods = sorted(set(sub.method), key=method_rank)
    for ax, (column, title, scale) in zip(axes, PANELS, strict=True):
        if column == "success":
            _success(ax, sub, methods, paper, task)
        else:
            _distribution(ax, sub, methods, column, scale or "linear", column in PAIRED_PANELS)
            for x, method in enumerate(methods):
                value = _paper_value(paper, task, method.split("#")[0], PAPER_COLUMNS[column])
                ax.plot(x, value, "kD", ms=6, mfc="none", zorder=4)
                if column == "sum_sq_acc" and "sum_sq_acc_paper" in sub:
                    computed = sub[sub.method == method].sum_sq_acc_paper.astype(float).mean()
                    ax.plot(x, computed, "kx", ms=7, mew=1.5, zorder=4)
        ax.set_xticks(range(len(methods)), [method_label(m) for m in methods])
        ax.set_title(f"Task {task}: {title}", fontsize="medium")
        ax.grid(axis="y", alpha=0.3)


def _legend(fig: Any) -> None:
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], color="k", marker="D", mfc="none", ls="", label="paper's mean (Fig. 5)"),
        Line2D([], [], color="k", marker="x", ls="", label="our mean as the paper computed it"),
        Line2D([], [], color="k", marker="|", ls="", ms=10, label="95 % Wilson interval"),
        Line2D([], [], color="0.5", alpha=0.5, label="one environment, every method"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize="small", frameon=False)


def plot_fig5(episodes: pd.DataFrame, out_dir: Path, title: str = "") -> list[Path]:
    """Draw Fig. 5 of ``episodes`` (one benchmark configuration) into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .table import paper_table

    paper = paper_table()
    out_dir.mkdir(parents=True, exist_ok=True)
    tasks = sorted(episodes.task.unique())
    written: list[Path] = []
    sets = [("fig5", tasks)] + [(f"fig5_task{t}", [t]) for t in tasks]
    for name, shown in sets:
        fig, axes = plt.subplots(
            len(shown), len(PANELS), figsize=(14, 2.9 * len(shown) + 0.9), squeeze=False
        )
        for row, task in zip(axes, shown, strict=True):
            _row(row, episodes[episodes.task == task], paper, int(task))
        fig.suptitle(title or "Fig. 5, reproduced: per task and method", fontsize="medium")
        _legend(fig)
        fig.tight_layout(rect=(0, 0.05 if len(shown) > 1 else 0.09, 1, 1))
        for suffix in ("png", "pdf"):
            path = out_dir / f"{name}.{suffix}"
            fig.savefig(path, dpi=110)
            written.append(path)
        plt.close(fig)
    return written


def plot_runs(runs: Path, out_dir: Path) -> list[Path]:
    """Fig. 5 of every benchmark configuration under ``runs`` (see the module notes)."""
    from .episodes import load_runs
    from .table import benchmarks

    groups = benchmarks(load_runs(runs))
    written = []
    for bench in groups:
        where = out_dir if len(groups) == 1 else out_dir / f"scene_{bench.scene_hash}"
        settings = " ".join(bench.overrides) or "default configuration"
        title = f"Fig. 5, reproduced from {runs} ({settings}; {len(bench.episodes)} episodes)"
        written += plot_fig5(bench.episodes, where, title)
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m analysis.fig5 [RUNS] [--out DIR]``."""
    from amex.app.argparsing import OneLineParser
    from amex.experiment.store import StoreError

    from . import print_written
    from .episodes import TableError

    parser = OneLineParser(prog="make figures", description="Fig. 5 as figures")
    parser.add_argument("runs", nargs="?", default="runs", type=Path)
    parser.add_argument("--out", default=default_out(), type=Path)
    args = parser.parse_args(argv)
    return print_written(
        "make figures", lambda: plot_runs(args.runs, args.out), (TableError, StoreError)
    )


if __name__ == "__main__":
    raise SystemExit(main())
