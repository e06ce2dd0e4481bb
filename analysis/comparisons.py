"""Paired comparisons on identical environments, and the paper's claims checked.

:func:`paired`: every two methods that ran the same environments of a task (a before b in
:data:`METHOD_ORDER`, then other methods by name); :func:`paired_stats`: any two sets of episodes
(the studies' cells). Per metric the mean difference a - b, a bootstrap 95 % interval and the
Wilcoxon signed-rank p-value. :func:`claims`: the paper's qualitative claims on the aggregates of
:func:`analysis.table.aggregate`, each "holds", "fails", "n/a", or "too few" when judged on fewer
than :data:`MIN_EPISODES` environments per method.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

METHOD_ORDER = ("amex", "dmp", "dmp_ps", "cr", "track")
MIN_EPISODES = 30  # fewer environments per method: a claim is "too few", not holds / fails
PAIRED_METRICS = ("success", "final_time", "sum_sq_acc", "sum_sq_acc_paper", "sum_sq_acc_t3")
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
    from scipy.stats import wilcoxon

    records = []
    for task in sorted(df.task.unique()):
        sub = df[df.task == task]
        methods = sorted(set(sub.method), key=method_rank)
        for i, a in enumerate(methods):
            for b in methods[i + 1 :]:
                wide = sub[sub.method.isin([a, b])].pivot(index="env", columns="method")
                for metric in (m for m in PAIRED_METRICS if m in sub):
                    d = (wide[(metric, a)].astype(float) - wide[(metric, b)].astype(float))
                    d = d.dropna().to_numpy()  # environments both ran, the metric recorded
                    if len(d) < 2:
                        continue
                    lo, hi = bootstrap_ci(d, seed=int(task))
                    p = 1.0 if np.all(d == 0) else float(wilcoxon(d, zero_method="zsplit").pvalue)
                    records.append(
                        {
                            "task": task,
                            "a": a,
                            "b": b,
                            "metric": metric,
                            "pairs": len(d),
                            "mean_diff": float(d.mean()),
                            "ci_low": lo,
                            "ci_high": hi,
                            "wilcoxon_p": p,
                        }
                    )
    return pd.DataFrame.from_records(records)


def paired_stats(
    a: pd.DataFrame, b: pd.DataFrame, metrics: Sequence[str] = STUDY_METRICS
) -> pd.DataFrame:
    """Episodes ``a`` minus episodes ``b`` on the environments both ran, one row per metric.

    Each row: pairs, the two means, the mean difference, its bootstrap 95 % interval
    (:func:`bootstrap_ci`) and the Wilcoxon signed-rank p (NaN below 2 pairs).
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
            }
        )
    return pd.DataFrame.from_records(records)


def claims(
    ours: pd.DataFrame, smoothness: str = "sum_sq_acc_mean", success: str = "success"
) -> list[tuple[str, str, str]]:
    """The paper's qualitative claims checked on our aggregates: (claim, verdict, evidence).

    ``smoothness`` is the column the two smoothness claims compare: ``sum_sq_acc_mean`` (exact)
    or ``sum_sq_acc_paper_mean`` (as the authors computed it, rounding noise included);
    ``success`` the success rate the first claim reads (``success_005``: at 0.05 m, as they
    counted it).
    """
    out: list[tuple[str, str, str]] = []
    paper_methods = ("amex", "dmp", "cr")
    have = set(ours.method)
    tasks = sorted(t for t in ours.task.unique() if t >= 1)

    def get(task: int, method: str, col: str) -> float:
        row = ours[(ours.task == task) & (ours.method == method)]
        return float(row[col].iloc[0]) if len(row) else math.nan

    def verdict(name: str, needed: tuple[str, ...], test, fmt) -> None:
        if not set(needed) <= have or not tasks:
            missing = ", ".join(sorted(set(needed) - have)) or "tasks 1-4"
            out.append((name, "n/a", f"needs {missing}"))
            return
        results = {t: test(t) for t in tasks}
        ok = all(results.values())
        evidence = "; ".join(f"task {t}: {fmt(t)}" for t in tasks)
        n = min(int(get(t, m, "episodes")) for t in tasks for m in needed)
        word = "holds" if ok else "fails"
        if n < MIN_EPISODES:
            word = f"too few (n = {n} < {MIN_EPISODES}); {word} so far"
        out.append((name, word, evidence))

    present = tuple(m for m in paper_methods if m in have)
    verdict(
        "all methods above 0.9 success",
        present or paper_methods,
        lambda t: all(get(t, m, success) > 0.9 for m in present),
        lambda t: ", ".join(f"{m} {get(t, m, success):.2f}" for m in present),
    )
    label = "as the paper computed it" if "paper" in smoothness else "exact"
    for claim, col in (
        (f"CR is the smoothest (lowest sum of squared accelerations, {label})", smoothness),
        (
            "CR is the smoothest at equal duration (median sum sq. acc. x final time^3; "
            "diagnostic)",
            "sum_sq_acc_t3_median",
        ),
    ):
        verdict(
            claim,
            paper_methods,
            lambda t, c=col: get(t, "cr", c) < min(get(t, "amex", c), get(t, "dmp", c)),
            lambda t, c=col: ", ".join(f"{m} {get(t, m, c):.3g}" for m in paper_methods),
        )
    verdict(
        f"AMEX is smoother than DMP ({label})",
        ("amex", "dmp"),
        lambda t: get(t, "amex", smoothness) < get(t, "dmp", smoothness),
        lambda t: f"amex {get(t, 'amex', smoothness):.3g} vs dmp {get(t, 'dmp', smoothness):.3g}",
    )
    verdict(
        "compute time CR >> AMEX > DMP (>> meaning 10x)",
        paper_methods,
        lambda t: (
            get(t, "cr", "compute_time_mean") > 10 * get(t, "amex", "compute_time_mean")
            and get(t, "amex", "compute_time_mean") > get(t, "dmp", "compute_time_mean")
        ),
        lambda t: ", ".join(f"{m} {get(t, m, 'compute_time_mean'):.2e}" for m in paper_methods),
    )
    verdict(
        "AMEX's final time spreads more than CR's",
        ("amex", "cr"),
        lambda t: get(t, "amex", "final_time_2std") > get(t, "cr", "final_time_2std"),
        lambda t: (
            f"2 std amex {get(t, 'amex', 'final_time_2std'):.2f} s vs cr "
            f"{get(t, 'cr', 'final_time_2std'):.2f} s"
        ),
    )
    return out
