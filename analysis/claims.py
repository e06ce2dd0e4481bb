"""The paper's five claims as test verdicts, per task, on one benchmark's episodes.

Each claim is a conjunction of tests (:mod:`analysis.decide` turns them into holds / fails /
inconclusive); the tests, on the environments every method of the claim ran, paired on
``(seed, env)``, intervals from :func:`analysis.inference.resamples` (seeds as replicates):

1. all methods above 0.9 success: per method the score test of rate = 0.9, whose inversion is
   the Wilson interval shown (sample size divided by the seeds' design effect);
2. CR is the smoothest: CR - AMEX and CR - DMP below 0 (:func:`smaller`);
3. AMEX is smoother than DMP: AMEX - DMP below 0 (:func:`smaller`);
4. compute time CR >> AMEX > DMP: the ratios of the median step time, CR / AMEX above 10 and
   AMEX / DMP above 1, on each step's thread CPU time (wall time for rows without it);
5. AMEX's final time spreads more than CR's: 2 std AMEX - 2 std CR above 0.

:func:`smaller` needs both the bootstrap interval of the mean paired difference and the Wilcoxon
signed-rank test on the same side (its p is the larger of the two). The bootstrap p of a
statistic against a threshold is twice the share of resamples on the far side.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .decide import Claim, Evidence, decide, fmt_p
from .inference import Interval, design_effect, percentile, resamples, wilcoxon, wilson_n

MIN_EPISODES = 30  # fewer environments per method: every verdict is inconclusive
SUCCESS_LEVEL = 0.9
COMPUTE_FACTOR = 10.0  # ">>" read as ten times
PAPER_METHODS = ("amex", "dmp", "cr")


def aligned(sub: pd.DataFrame, methods: tuple[str, ...], column: str) -> pd.DataFrame:
    """``column`` of ``methods``, a column each, on the (seed, env) every one of them ran."""
    wide = sub[sub.method.isin(methods)].set_index(["seed", "env", "method"])[column]
    wide = wide.astype(float).unstack("method")
    return wide.reindex(columns=list(methods)).dropna()


def _seeds(wide: pd.DataFrame) -> np.ndarray:
    return wide.index.get_level_values("seed").to_numpy()


def boot_p(values: np.ndarray, threshold: float) -> float:
    """Twice the share of bootstrap ``values`` on the far side of ``threshold`` from most."""
    values = values[np.isfinite(values)]
    if not len(values):
        return 1.0
    below, above = np.mean(values <= threshold), np.mean(values >= threshold)
    return float(min(1.0, 2 * min(below, above)))


def smaller(a: np.ndarray, b: np.ndarray, seeds: np.ndarray, label: str) -> Evidence:
    """Evidence of "a is smaller than b" on paired values (module notes)."""
    d = a - b
    means = d[resamples(seeds)].mean(axis=1)
    estimate = Interval(float(d.mean()), *percentile(means))
    p_boot = boot_p(means, 0.0)
    p_w, direction = wilcoxon(d)
    supports = estimate.estimate < 0
    agree = direction == (-1 if supports else 1)
    p = max(p_boot, p_w) if agree else 1.0
    note = "" if agree else ", median the other way"
    return Evidence(supports, p, f"{label} {estimate.text()}, {fmt_p(p)}{note}")


def above(stat: np.ndarray, estimate: float, threshold: float, label: str, fmt: str) -> Evidence:
    """Evidence of "a statistic is above ``threshold``" from its bootstrap values ``stat``."""
    interval = Interval(estimate, *percentile(stat))
    p = boot_p(stat, threshold)
    return Evidence(estimate > threshold, p, f"{label} {interval.text(fmt)}, {fmt_p(p)}")


def success_test(success: np.ndarray, seeds: np.ndarray, label: str) -> Evidence:
    """Score test of a success rate against :data:`SUCCESS_LEVEL` (the Wilson interval's)."""
    from scipy.stats import norm

    n = len(success) / design_effect(success, seeds)
    rate = float(np.mean(success))
    z = (rate - SUCCESS_LEVEL) / math.sqrt(SUCCESS_LEVEL * (1 - SUCCESS_LEVEL) / n)
    p = float(2 * norm.sf(abs(z)))
    interval = Interval(rate, *wilson_n(rate, n))
    return Evidence(rate > SUCCESS_LEVEL, p, f"{label} {interval.text('.2f')}")


def compute_column(sub: pd.DataFrame) -> tuple[str, str]:
    """The step-time column a task's compute claim reads, and its name in the tables."""
    cpu = sub.get("compute_cpu_median")
    if cpu is not None and np.isfinite(cpu.astype(float)).all():
        return "compute_cpu_median", "CPU"
    return "compute_time_median", "wall"


def compute_claim(sub: pd.DataFrame, column: str = "") -> list[Evidence]:
    """Claim 4's tests on one task's episodes ``sub``: CR / AMEX > 10, AMEX / DMP > 1.

    ``column``: the step-time column; by default :func:`compute_column`'s choice.
    """
    if column:
        measure = "CPU" if "cpu" in column else "wall"
    else:
        column, measure = compute_column(sub)
    wide = aligned(sub, PAPER_METHODS, column)
    if not len(wide):
        return []
    idx = resamples(_seeds(wide))
    medians = {m: np.median(wide[m].to_numpy()[idx], axis=1) for m in PAPER_METHODS}
    point = {m: float(np.median(wide[m])) for m in PAPER_METHODS}
    return [
        above(
            medians["cr"] / medians["amex"],
            point["cr"] / point["amex"],
            COMPUTE_FACTOR,
            f"CR/AMEX ({measure})",
            ".3g",
        ),
        above(
            medians["amex"] / medians["dmp"], point["amex"] / point["dmp"], 1.0, "AMEX/DMP", ".3g"
        ),
    ]


def _spread_test(sub: pd.DataFrame) -> list[Evidence]:
    wide = aligned(sub, ("amex", "cr"), "final_time")
    if not len(wide):
        return []
    idx = resamples(_seeds(wide))
    a, c = wide.amex.to_numpy(), wide.cr.to_numpy()
    stat = 2 * (a[idx].std(axis=1) - c[idx].std(axis=1))
    label = "2 std AMEX - CR [s]"
    return [above(stat, 2 * float(a.std() - c.std()), 0.0, label, ".2f")]


def _smoother(sub: pd.DataFrame, a: str, others: tuple[str, ...], column: str) -> list[Evidence]:
    tests = []
    for b in others:
        wide = aligned(sub, (a, b), column)
        if len(wide):
            label = f"{a.upper()} - {b.upper()}"
            tests.append(smaller(wide[a].to_numpy(), wide[b].to_numpy(), _seeds(wide), label))
    return tests


def _success_tests(sub: pd.DataFrame, column: str) -> list[Evidence]:
    tests = []
    for m in PAPER_METHODS:
        g = sub[sub.method == m]
        if len(g):
            tests.append(success_test(g[column].to_numpy(bool), g.seed.to_numpy(), m))
    return tests


def claim_names(smoothness: str) -> tuple[str, ...]:
    """The five claims' names; ``smoothness`` says which sum of squared accelerations."""
    label = "as the paper computed it" if "paper" in smoothness else "exact"
    return (
        "all methods above 0.9 success",
        f"CR is the smoothest (lowest sum of squared accelerations, {label})",
        f"AMEX is smoother than DMP ({label})",
        "compute time CR >> AMEX > DMP (>> meaning 10x)",
        "AMEX's final time spreads more than CR's",
    )


def claims(
    episodes: pd.DataFrame, smoothness: str = "sum_sq_acc", success: str = "success"
) -> list[Claim]:
    """The five claims on one benchmark's ``episodes`` (tasks >= 1), in :func:`claim_names` order.

    ``smoothness``: ``sum_sq_acc`` (exact) or ``sum_sq_acc_paper`` (as the authors computed it);
    ``success``: ``success`` (0.03 m) or ``success_005`` (0.05 m, as they counted it).
    """
    have = set(episodes.method)
    tasks = sorted(int(t) for t in episodes.task.unique() if t >= 1)
    names = claim_names(smoothness)
    builders = (
        (PAPER_METHODS, lambda s: _success_tests(s, success)),
        (PAPER_METHODS, lambda s: _smoother(s, "cr", ("amex", "dmp"), smoothness)),
        (("amex", "dmp"), lambda s: _smoother(s, "amex", ("dmp",), smoothness)),
        (PAPER_METHODS, compute_claim),
        (("amex", "cr"), _spread_test),
    )
    out = []
    for name, (needed, build) in zip(names, builders, strict=True):
        if not set(needed) <= have or not tasks:
            out.append(decide(name, {}))
            continue
        per_task = {t: build(episodes[episodes.task == t]) for t in tasks}
        counts = episodes[episodes.method.isin(needed) & (episodes.task >= 1)]
        n = int(counts.groupby(["task", "method"]).size().min())
        too_few = f"n = {n} < {MIN_EPISODES}" if n < MIN_EPISODES else ""
        out.append(decide(name, per_task, too_few))
    return out
