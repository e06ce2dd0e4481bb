"""Tests against the paper's printed Fig. 5: its claims on its numbers, and ours against them.

The paper gives per task and method the mean and 2 std over n = 150 environments (its success
rate to two digits) and nothing else, so every test here is a two-sample test on summaries: the
paper's standard error is (2 std / 2) / sqrt(150), its rate is taken as round(150 p) successes of
150. Assumptions: the two samples are independent (other environment draws), their means are
near normal at these n (central limit theorem; the sums of squared accelerations, whose 2 std
exceeds their mean, least so), and the printed std is the sample's.

* :func:`paper_claims`: the five claims on the paper's own numbers. Unpaired (the paper gives no
  environment-level data, so a paired test is impossible: these are conservative): score test
  of each rate against 0.9 (Wilson), Welch's z on the smoothness means, the log-ratio z of the
  compute means, the F test of the two final-time variances.
* :func:`reproduction`: ours against the paper per cell, as equivalence within a margin
  (:data:`MARGINS`, the reproduction's acceptance limits): holds when the 95 % interval of the
  difference lies inside the margin, fails when it lies outside (at the Bonferroni level over the
  cells, :mod:`analysis.decide`), otherwise inconclusive. Our standard error is the bootstrap's
  (seeds as replicates); the difference's SE is sqrt(SE_ours² + SE_paper²).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pandas as pd

from .claims import COMPUTE_FACTOR, MIN_EPISODES, PAPER_METHODS, SUCCESS_LEVEL, claim_names
from .decide import Claim, Evidence, decide, fmt_p
from .inference import ALPHA, Interval, Z, design_effect, newcombe, resamples, wilson_n

PAPER_N = 150


class Margin(NamedTuple):
    """A reproduction criterion: our column, the paper's, the margin and how it is read."""

    title: str
    ours: str
    paper: str
    margin: float
    relative: bool  # True: ours / paper within 1 +- margin; False: ours - paper within +- margin
    fmt: str


MARGINS = (
    Margin("mean final time [s], within 0.15 s", "final_time", "final_time", 0.15, False, "+.2f"),
    Margin("success at 0.05 m, within 0.06", "success_005", "success", 0.06, False, "+.2f"),
    Margin(
        "sum sq. acc. as the paper computed it, ratio within 25 %",
        "sum_sq_acc_paper",
        "sum_sq_acc",
        0.25,
        True,
        ".2f",
    ),
)


def _paper(paper: pd.DataFrame, task: int, method: str) -> pd.Series | None:
    row = paper[(paper.task == task) & (paper.method == method)]
    return row.iloc[0] if len(row) else None


def _se(two_std: float, n: int = PAPER_N) -> float:
    return two_std / 2 / math.sqrt(n)


def _z_test(
    estimate: float, se: float, threshold: float, supports_above: bool
) -> tuple[bool, float]:
    from scipy.stats import norm

    z = (estimate - threshold) / se if se > 0 else math.copysign(math.inf, estimate - threshold)
    return (z > 0) == supports_above, float(min(1.0, 2 * norm.sf(abs(z))))


def _smoother(rows: dict[str, pd.Series], a: str, b: str) -> Evidence:
    ra, rb = rows[a], rows[b]
    d = float(ra.sum_sq_acc_mean - rb.sum_sq_acc_mean)
    se = math.hypot(_se(ra.sum_sq_acc_2std), _se(rb.sum_sq_acc_2std))
    ok, p = _z_test(d, se, 0.0, False)
    text = f"{a.upper()} - {b.upper()} {Interval(d, d - Z * se, d + Z * se).text()}"
    return Evidence(ok, p, f"{text}, {fmt_p(p)}")


def _ratio(rows: dict[str, pd.Series], a: str, b: str, threshold: float) -> Evidence:
    ra, rb = rows[a], rows[b]
    r = float(ra.compute_time_mean / rb.compute_time_mean)
    s = math.hypot(
        _se(ra.compute_time_2std) / ra.compute_time_mean,
        _se(rb.compute_time_2std) / rb.compute_time_mean,
    )
    ok, p = _z_test(math.log(r), s, math.log(threshold), True)
    interval = Interval(r, r * math.exp(-Z * s), r * math.exp(Z * s))
    return Evidence(ok, p, f"{a.upper()}/{b.upper()} (mean) {interval.text()}, {fmt_p(p)}")


def _spread(rows: dict[str, pd.Series]) -> list[Evidence]:
    from scipy.stats import f as fisher

    va, vc = (float(rows[m].final_time_2std / 2) ** 2 for m in ("amex", "cr"))
    df = PAPER_N - 1
    if vc <= 0:
        return []
    f_ratio = va / vc
    p = float(min(1.0, 2 * min(fisher.cdf(f_ratio, df, df), fisher.sf(f_ratio, df, df))))
    low = f_ratio / float(fisher.ppf(1 - ALPHA / 2, df, df))
    high = f_ratio / float(fisher.ppf(ALPHA / 2, df, df))
    return [
        Evidence(f_ratio > 1, p, f"var AMEX/CR {Interval(f_ratio, low, high).text()}, {fmt_p(p)}")
    ]


def _success(rows: dict[str, pd.Series]) -> list[Evidence]:
    tests = []
    for m, r in rows.items():
        rate = float(r.success)
        ok, p = _z_test(rate, math.sqrt(0.09 / PAPER_N), SUCCESS_LEVEL, True)
        tests.append(Evidence(ok, p, f"{m} {Interval(rate, *wilson_n(rate, PAPER_N)).text('.2f')}"))
    return tests


def paper_claims(paper: pd.DataFrame, smoothness: str = "sum_sq_acc") -> list[Claim]:
    """The five claims on the paper's printed numbers (module notes); ``paper``: its Fig. 5."""
    tests: list[dict[int, list[Evidence]]] = [{}, {}, {}, {}, {}]
    for task in sorted(int(t) for t in paper.task.unique()):
        found = {m: _paper(paper, task, m) for m in PAPER_METHODS}
        rows = {m: r for m, r in found.items() if r is not None}
        if len(rows) < len(PAPER_METHODS):
            continue
        tests[0][task] = _success(rows)
        tests[1][task] = [_smoother(rows, "cr", "amex"), _smoother(rows, "cr", "dmp")]
        tests[2][task] = [_smoother(rows, "amex", "dmp")]
        tests[3][task] = [
            _ratio(rows, "cr", "amex", COMPUTE_FACTOR),
            _ratio(rows, "amex", "dmp", 1),
        ]
        tests[4][task] = _spread(rows)
    return [decide(n, t) for n, t in zip(claim_names(smoothness), tests, strict=True)]


def _equivalence(estimate: Interval, se: float, margin: float, center: float, fmt: str) -> Evidence:
    """Equivalence of ``estimate`` to ``center`` within ``margin`` (normal, SE ``se``)."""
    from scipy.stats import norm

    gap = abs(estimate.estimate - center)
    if se <= 0:
        p = 0.0 if gap != margin else 1.0
    elif gap < margin:  # two one-sided tests, doubled to compare with ALPHA like the interval
        p = float(min(1.0, 2 * norm.sf((margin - gap) / se)))
    else:
        p = float(min(1.0, 2 * norm.sf((gap - margin) / se)))
    text = f"{estimate.text(fmt)}, SE {se:.2g}"
    return Evidence(gap < margin, p, text)


def _cell_test(sub: pd.DataFrame, row: pd.Series, criterion: Margin) -> Evidence | None:
    values = sub[criterion.ours].to_numpy(dtype=float)
    seeds = sub.seed.to_numpy()
    if not len(values) or not np.isfinite(values).all():
        return None
    if criterion.ours.startswith("success"):
        rate, n = float(values.mean()), len(values) / design_effect(values > 0.5, seeds)
        interval = newcombe(rate * n, n, round(float(row.success) * PAPER_N), PAPER_N)
        se = (interval.high - interval.low) / (2 * Z)
        return _equivalence(interval, se, criterion.margin, 0.0, criterion.fmt)
    means = values[resamples(seeds)].mean(axis=1)
    ours_se = float(means.std())
    paper_mean = float(row[f"{criterion.paper}_mean"])
    paper_se = _se(float(row[f"{criterion.paper}_2std"]))
    if criterion.relative:
        r = float(values.mean()) / paper_mean
        s = math.hypot(ours_se / values.mean(), paper_se / paper_mean)
        interval = Interval(r, r * math.exp(-Z * s), r * math.exp(Z * s))
        return _equivalence(interval, r * s, criterion.margin, 1.0, criterion.fmt)
    d = float(values.mean()) - paper_mean
    se = math.hypot(ours_se, paper_se)
    return _equivalence(Interval(d, d - Z * se, d + Z * se), se, criterion.margin, 0.0, "+.2f")


def reproduction(episodes: pd.DataFrame, paper: pd.DataFrame) -> list[Claim]:
    """Ours against the paper, one claim per :data:`MARGINS` entry, a verdict per cell.

    The per-task verdicts of :class:`Claim` are keyed here by cell: ``10 * task + i`` with i the
    method's index in :data:`PAPER_METHODS` (see :func:`cell_label`).
    """
    out = []
    for criterion in MARGINS:
        tests: dict[int, list[Evidence]] = {}
        smallest = math.inf
        for task in sorted(int(t) for t in episodes.task.unique() if t >= 1):
            for i, method in enumerate(PAPER_METHODS):
                sub = episodes[(episodes.task == task) & (episodes.method == method)]
                row = _paper(paper, task, method)
                if row is None or not len(sub):
                    continue
                test = _cell_test(sub, row, criterion)
                if test is not None:
                    tests[10 * task + i] = [test]
                    smallest = min(smallest, len(sub))
        too_few = f"n = {smallest} < {MIN_EPISODES}" if smallest < MIN_EPISODES else ""
        out.append(decide(criterion.title, tests, too_few, cell_label))
    return out


def cell_label(key: int) -> str:
    """``T3 dmp`` for a cell key of :func:`reproduction`."""
    return f"T{key // 10} {PAPER_METHODS[key % 10]}"
