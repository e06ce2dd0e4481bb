"""Per cell: the figures of Fig. 5 with their intervals, and the spread within and between seeds.

* :func:`intervals`: per task and method the seeds and environments, the success rate with its
  Wilson interval (:func:`analysis.inference.success_interval`), and the mean final time, its
  2 std and the mean sum of squared accelerations with cluster-bootstrap intervals (seeds as
  replicates; one seed: environments).
* :func:`seed_spread`: for cells that pooled several seeds, per metric the pooled mean (its
  interval as in :func:`intervals`), the
  within-seed 2 std (root of the mean within-seed variance), the between-seed 2 std of the seed
  means beside what the within-seed spread alone predicts for them (within 2 std / sqrt(n per
  seed)), and the one-way ANOVA p of a seed effect. Seeds only pick environments, so the seed
  means should scatter as predicted; a small p says they do not.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .comparisons import method_rank
from .inference import Interval, percentile, resamples, success_interval

#: The metrics of :func:`seed_spread`: column, name, format.
SPREAD_METRICS = (
    ("final_time", "final time [s]", ".2f"),
    ("sum_sq_acc", "sum sq. acc. (exact)", ".3g"),
    ("success", "success", ".2f"),
)


def _cells(episodes: pd.DataFrame):
    for task in sorted(episodes.task.unique()):
        sub = episodes[episodes.task == task]
        for method in sorted(set(sub.method), key=method_rank):
            yield int(task), method, sub[sub.method == method]


def _envs(g: pd.DataFrame) -> str:
    sizes = g.groupby("seed").size()
    return str(len(g)) if len(sizes) == 1 else f"{len(g)} ({'+'.join(map(str, sizes))})"


def intervals(episodes: pd.DataFrame) -> pd.DataFrame:
    """The display table of :func:`intervals` (module notes)."""
    rows = []
    for task, method, g in _cells(episodes):
        seeds = g.seed.to_numpy()
        idx = resamples(seeds)
        ft = g.final_time.to_numpy(dtype=float)
        acc = g.sum_sq_acc.to_numpy(dtype=float)
        two_std = Interval(2 * float(ft.std()), *percentile(2 * ft[idx].std(axis=1)))
        rows.append(
            {
                "task": task,
                "method": method,
                "seeds": len(set(seeds)),
                "environments": _envs(g),
                "success [95% CI]": success_interval(g.success.to_numpy(bool), seeds).text(".2f"),
                "final time [s]": Interval(ft.mean(), *percentile(ft[idx].mean(1))).text(".2f"),
                "final time 2 std [s]": two_std.text(".2f"),
                "sum sq. acc. (exact)": Interval(acc.mean(), *percentile(acc[idx].mean(1))).text(),
            }
        )
    return pd.DataFrame.from_records(rows)


def anova_p(values: np.ndarray, seeds: np.ndarray) -> float:
    """One-way ANOVA p of a difference between the seeds' means (NaN: fewer than 2 seeds)."""
    from scipy.stats import f_oneway

    groups = [values[seeds == s] for s in np.unique(seeds)]
    if len(groups) < 2 or min(len(g) for g in groups) < 2:
        return math.nan
    if all(np.all(g == groups[0][0]) for g in groups):
        return 1.0
    return float(f_oneway(*groups).pvalue)


def seed_spread(episodes: pd.DataFrame) -> pd.DataFrame:
    """The display table of :func:`seed_spread` (module notes); empty when no cell pooled."""
    rows = []
    for task, method, g in _cells(episodes):
        seeds = g.seed.to_numpy()
        labels = np.unique(seeds)
        if len(labels) < 2:
            continue
        for column, name, fmt in SPREAD_METRICS:
            x = g[column].to_numpy(dtype=float)
            means = np.array([x[seeds == s].mean() for s in labels])
            sizes = np.array([np.sum(seeds == s) for s in labels])
            within = math.sqrt(
                sum(x[seeds == s].var() * len(x[seeds == s]) for s in labels) / len(x)
            )
            if column == "success":
                pooled = success_interval(x > 0.5, seeds)
            else:
                pooled = Interval(float(x.mean()), *percentile(x[resamples(seeds)].mean(axis=1)))
            rows.append(
                {
                    "task": task,
                    "method": method,
                    "metric": name,
                    "seeds": len(labels),
                    "environments": _envs(g),
                    "pooled mean [95% CI, seeds as replicates]": pooled.text(fmt),
                    "within-seed 2 std": f"{2 * within:{fmt}}",
                    "between-seed 2 std of seed means": f"{2 * means.std(ddof=1):{fmt}}",
                    "predicted by within": f"{2 * within / math.sqrt(sizes.mean()):{fmt}}",
                    "seed effect p": f"{anova_p(x, seeds):.2g}",
                    "seed means": ", ".join(f"{m:{fmt}}" for m in means),
                }
            )
    return pd.DataFrame.from_records(rows)
