"""Paired comparisons on identical environments.

:func:`paired`: every two methods that ran the same environments of a task (a before b in
:data:`METHOD_ORDER`, then other methods by name), an environment being ``(seed, env)``;
:func:`paired_stats`: any two sets of episodes (the studies' cells). Per metric the mean
difference a - b, a bootstrap 95 % interval (in :func:`paired`, seeds as replicates:
:func:`analysis.inference.resamples`) and a paired test: Wilcoxon signed-rank for numbers, the
exact McNemar test for success and collision indicators. The paper's claims: :mod:`analysis.claims`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

METHOD_ORDER = ("amex", "dmp", "dmp_ps", "cr", "mppi", "track")
PAIRED_METRICS = ("success", "final_time", "sum_sq_acc", "sum_sq_acc_paper", "sum_sq_acc_t3")
BOOLEAN_METRICS = ("success", "success_005", "collided")  # paired by McNemar's test
#: The metrics :func:`paired_stats` compares by default (the studies' cells).
STUDY_METRICS = ("final_time", "success", "sum_sq_acc", "final_distance")
BOOTSTRAP = 10_000


def bootstrap_ci(d: np.ndarray, seed: int = 0, n: int = BOOTSTRAP) -> tuple[float, float]:
    """95 % percentile bootstrap interval of the mean of ``d`` (seeded: reproducible)."""
    rng = np.random.default_rng(seed)
    means = rng.choice(d, size=(n, len(d)), replace=True).mean(axis=1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return float(lo), float(hi)


def method_rank(name: str) -> tuple[int, str]:
    """Sort key: the paper's methods and ours in :data:`METHOD_ORDER`, then others by name."""
    base = name.split("#")[0]
    order = METHOD_ORDER.index(base) if base in METHOD_ORDER else len(METHOD_ORDER)
    return order, name


def paired(df: pd.DataFrame) -> pd.DataFrame:
    """Paired comparisons (a minus b) of every two methods on the environments both ran."""
    from .inference import mcnemar_p, mean_interval, resamples, wilcoxon

    if "seed" not in df:
        df = df.assign(seed=0)
    records = []
    for task in sorted(df.task.unique()):
        sub = df[df.task == task]
        methods = sorted(set(sub.method), key=method_rank)
        for i, a in enumerate(methods):
            for b in methods[i + 1 :]:
                both = sub[sub.method.isin([a, b])]
                wide = both.pivot(index=["seed", "env"], columns="method")
                for metric in (m for m in PAIRED_METRICS if m in sub):
                    pair = wide[[(metric, a), (metric, b)]].astype(float).dropna()
                    if len(pair) < 2:  # environments both ran, the metric recorded
                        continue
                    va, vb = pair[(metric, a)].to_numpy(), pair[(metric, b)].to_numpy()
                    d = va - vb
                    ci = mean_interval(d, resamples(pair.index.get_level_values("seed")))
                    if metric in BOOLEAN_METRICS:
                        test, p = "mcnemar", mcnemar_p(va > 0.5, vb > 0.5)
                    else:
                        test, p = "wilcoxon", wilcoxon(d)[0]
                    records.append(
                        {
                            "task": task,
                            "a": a,
                            "b": b,
                            "metric": metric,
                            "pairs": len(d),
                            "mean_diff": ci.estimate,
                            "ci_low": ci.low,
                            "ci_high": ci.high,
                            "test": test,
                            "p": p,
                        }
                    )
    return pd.DataFrame.from_records(records)


def paired_stats(
    a: pd.DataFrame, b: pd.DataFrame, metrics: Sequence[str] = STUDY_METRICS
) -> pd.DataFrame:
    """Episodes ``a`` minus episodes ``b`` on the environments both ran, one row per metric.

    Each row: pairs, the two means, the mean difference, its bootstrap 95 % interval
    (:func:`bootstrap_ci`) and the Wilcoxon signed-rank p (NaN below 2 pairs), as ``wilcoxon_p``
    and as ``test`` / ``p`` (the columns of :func:`paired`).
    """
    from scipy.stats import wilcoxon

    wide_a, wide_b = a.set_index("env"), b.set_index("env")
    envs = wide_a.index.intersection(wide_b.index).sort_values()
    records = []
    for metric in metrics:
        va = wide_a.loc[envs, metric].astype(float).to_numpy()
        vb = wide_b.loc[envs, metric].astype(float).to_numpy()
        d = va - vb
        lo, hi = bootstrap_ci(d) if len(d) else (math.nan, math.nan)
        p = math.nan
        if len(d) >= 2:
            p = 1.0 if np.all(d == 0) else float(wilcoxon(d, zero_method="zsplit").pvalue)
        records.append(
            {
                "metric": metric,
                "pairs": len(d),
                "mean_a": float(va.mean()) if len(d) else math.nan,
                "mean_b": float(vb.mean()) if len(d) else math.nan,
                "mean_diff": float(d.mean()) if len(d) else math.nan,
                "ci_low": lo,
                "ci_high": hi,
                "wilcoxon_p": p,
                "test": "wilcoxon",  # the columns of paired()'s rows, for paired_markdown
                "p": p,
            }
        )
    return pd.DataFrame.from_records(records)
