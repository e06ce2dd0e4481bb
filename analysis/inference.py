"""The tests and intervals every verdict of the reports rests on (``docs/statistics.md``).

* :func:`resamples`: bootstrap resamples of a cell's environments, seeds as replicates (a
  two-stage cluster bootstrap: seeds with replacement, then environments within each drawn
  seed); with one seed the ordinary bootstrap. Seeded: every table is reproducible bit for bit.
* :func:`paired_location`: a paired difference a - b on the same environments: its mean, the
  percentile interval of the mean over :func:`resamples`, and the Wilcoxon signed-rank test.
* :func:`mcnemar_p`: the exact McNemar test of two paired success indicators.
* :func:`success_interval`: the Wilson interval of a success rate, its sample size divided by
  the design effect of the seeds (Kish) when there are several.
* Against a published mean and std (the paper's n = 150): :func:`welch`, :func:`newcombe`,
  :func:`ratio_interval`.

Every interval is two-sided at level 1 - :data:`ALPHA`; a verdict is the position of an interval
relative to a threshold (:func:`side`), so three outcomes: above, below, or straddling it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

ALPHA = 0.05  # two-sided level of every test and interval of the reports
Z = 1.959963984540054  # the standard normal's 1 - ALPHA / 2 quantile
BOOTSTRAP = 10_000  # resamples per interval
SEED = 20140914  # the bootstrap's seed (IROS 2014); every table draws the same resamples


class Interval(NamedTuple):
    """An estimate and its two-sided 1 - ALPHA interval."""

    estimate: float
    low: float
    high: float

    def text(self, fmt: str = ".3g") -> str:
        """``0.87 [0.81, 0.92]``."""
        return f"{self.estimate:{fmt}} [{self.low:{fmt}}, {self.high:{fmt}}]"


class PairedTest(NamedTuple):
    """A paired difference a - b: mean with interval, Wilcoxon p and the side it points to."""

    pairs: int
    mean: Interval
    p: float  # Wilcoxon signed-rank, two-sided (zsplit: zero differences split between signs)
    direction: int  # -1: a below b, +1: a above b, 0: no difference at all


def resamples(seeds: np.ndarray, n: int = BOOTSTRAP, seed: int = SEED) -> np.ndarray:
    """Row indices of ``n`` cluster-bootstrap resamples, shape (n, len(seeds)).

    ``seeds[i]`` is the scene seed of row i (rows of one seed contiguous or not). Each resample
    draws as many seeds as there are, with replacement, and for slot j (the j-th distinct seed,
    with m_j rows) m_j rows with replacement from the seed drawn into it. One seed: the ordinary
    bootstrap of the rows.
    """
    seeds = np.asarray(seeds)
    rng = np.random.default_rng(seed)
    groups = [np.flatnonzero(seeds == s) for s in np.unique(seeds)]
    sizes = np.array([len(g) for g in groups])
    if len(groups) == 1:
        return rng.integers(0, sizes[0], size=(n, sizes[0]))
    order = np.concatenate(groups)  # rows grouped by seed; group k at starts[k]
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    drawn = rng.integers(0, len(groups), size=(n, len(groups)))
    parts = []
    for j, m in enumerate(sizes):
        k = drawn[:, j]
        within = np.floor(rng.random((n, m)) * sizes[k][:, None]).astype(int)
        parts.append(order[starts[k][:, None] + within])
    return np.concatenate(parts, axis=1)


def percentile(values: np.ndarray) -> tuple[float, float]:
    """The 1 - ALPHA percentile interval of bootstrap ``values`` (NaN ones left out)."""
    values = values[np.isfinite(values)]
    if not len(values):
        return math.nan, math.nan
    lo, hi = np.percentile(values, [100 * ALPHA / 2, 100 * (1 - ALPHA / 2)])
    return float(lo), float(hi)


def mean_interval(x: np.ndarray, idx: np.ndarray) -> Interval:
    """The mean of ``x`` and its percentile interval over the resamples ``idx``."""
    return Interval(float(x.mean()), *percentile(x[idx].mean(axis=1)))


def wilcoxon(d: np.ndarray) -> tuple[float, int]:
    """Two-sided Wilcoxon signed-rank p of the paired differences ``d`` and their side."""
    from scipy.stats import wilcoxon as test

    if len(d) < 2 or np.all(d == 0):
        return 1.0, 0
    less = float(test(d, zero_method="zsplit", alternative="less").pvalue)
    greater = float(test(d, zero_method="zsplit", alternative="greater").pvalue)
    return min(1.0, 2 * min(less, greater)), (-1 if less < greater else 1)


def paired_location(d: np.ndarray, idx: np.ndarray) -> PairedTest:
    """Paired differences ``d`` (environments aligned with the resamples ``idx``) tested."""
    p, direction = wilcoxon(d)
    return PairedTest(len(d), mean_interval(d, idx), p, direction)


def mcnemar_p(a: np.ndarray, b: np.ndarray) -> float:
    """Exact McNemar p (two-sided binomial test on the discordant pairs) of paired booleans."""
    from scipy.stats import binomtest

    only_a, only_b = int(np.sum(a & ~b)), int(np.sum(~a & b))
    if only_a + only_b == 0:
        return 1.0
    return float(binomtest(only_a, only_a + only_b, 0.5).pvalue)


def design_effect(successes: np.ndarray, seeds: np.ndarray) -> float:
    """Kish's design effect 1 + (m - 1) ICC of 0/1 outcomes clustered by seed (>= 1).

    ICC: the one-way ANOVA estimate, truncated at 0; m the mean cluster size. 1 for one seed.
    """
    labels = np.unique(seeds)
    if len(labels) < 2:
        return 1.0
    y = successes.astype(float)
    groups = [y[seeds == s] for s in labels]
    k, n = len(groups), len(y)
    m = (n - sum(len(g) ** 2 for g in groups) / n) / (k - 1)
    between = sum(len(g) * (g.mean() - y.mean()) ** 2 for g in groups) / (k - 1)
    within = sum(((g - g.mean()) ** 2).sum() for g in groups) / (n - k)
    icc = 0.0 if between <= within else (between - within) / (between + (m - 1) * within)
    return 1.0 + (float(np.mean([len(g) for g in groups])) - 1.0) * icc


def success_interval(successes: np.ndarray, seeds: np.ndarray) -> Interval:
    """Wilson interval of the rate of ``successes``, n divided by the seeds' design effect."""
    n = len(successes) / design_effect(successes, seeds)
    rate = float(np.mean(successes)) if len(successes) else math.nan
    return Interval(rate, *wilson_n(rate, n))


def wilson_n(rate: float, n: float) -> tuple[float, float]:
    """Wilson interval of ``rate`` observed on an (effective, maybe fractional) sample size n."""
    if n <= 0 or math.isnan(rate):
        return math.nan, math.nan
    denominator = 1 + Z**2 / n
    center = (rate + Z**2 / (2 * n)) / denominator
    half = Z * math.sqrt(rate * (1 - rate) / n + Z**2 / (4 * n**2)) / denominator
    return max(center - half, 0.0), min(center + half, 1.0)


def side(interval: Interval | tuple[float, float], threshold: float) -> int:
    """+1 when the whole interval lies above ``threshold``, -1 below, 0 when it holds it."""
    low, high = interval[-2], interval[-1]
    if math.isnan(low) or math.isnan(high):
        return 0
    return 1 if low > threshold else -1 if high < threshold else 0


# ------------------------------------------------------- against a published mean and std


def welch(mean_a: float, sd_a: float, n_a: int, mean_b: float, sd_b: float, n_b: int):
    """Welch's two-sample t on summaries: (difference a - b as an Interval, its SE, p)."""
    from scipy.stats import t

    va, vb = sd_a**2 / n_a, sd_b**2 / n_b
    se = math.sqrt(va + vb)
    diff = mean_a - mean_b
    if se == 0:
        return Interval(diff, diff, diff), 0.0, (1.0 if diff == 0 else 0.0)
    df = (va + vb) ** 2 / (va**2 / (n_a - 1) + vb**2 / (n_b - 1))
    q = float(t.ppf(1 - ALPHA / 2, df))
    p = float(2 * t.sf(abs(diff) / se, df))
    return Interval(diff, diff - q * se, diff + q * se), se, p


def newcombe(k_a: int, n_a: float, k_b: int, n_b: int) -> Interval:
    """Newcombe's hybrid score interval of the difference of two independent rates a - b."""
    pa, pb = k_a / n_a, k_b / n_b
    la, ua = wilson_n(pa, n_a)
    lb, ub = wilson_n(pb, n_b)
    d = pa - pb
    low = d - math.sqrt((pa - la) ** 2 + (ub - pb) ** 2)
    high = d + math.sqrt((ua - pa) ** 2 + (pb - lb) ** 2)
    return Interval(d, low, high)


def fisher_p(k_a: int, n_a: int, k_b: int, n_b: int) -> float:
    """Two-sided Fisher exact p of two independent rates."""
    from scipy.stats import fisher_exact

    table = [[k_a, n_a - k_a], [k_b, n_b - k_b]]
    return float(fisher_exact(table).pvalue)


def ratio_interval(mean_a: float, se_a: float, mean_b: float, se_b: float) -> Interval:
    """a / b of two independent means, normal interval of its logarithm (delta method)."""
    if mean_a <= 0 or mean_b <= 0:
        return Interval(math.nan, math.nan, math.nan)
    r = mean_a / mean_b
    s = math.sqrt((se_a / mean_a) ** 2 + (se_b / mean_b) ** 2)
    return Interval(r, r * math.exp(-Z * s), r * math.exp(Z * s))
