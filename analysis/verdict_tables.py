"""The verdicts of :mod:`analysis.claims` and :mod:`analysis.vs_paper` as Markdown tables."""

from __future__ import annotations

import pandas as pd

from .claims import PAPER_METHODS, claims
from .decide import Claim
from .inference import ALPHA, BOOTSTRAP
from .markdown import markdown_table
from .spread import intervals, seed_spread
from .vs_paper import MARGINS, cell_label, reproduction

POLICY = (
    f"Verdicts at α = {ALPHA}: a claim holds when every test it makes supports it at p < {ALPHA} "
    "(intersection-union, no adjustment), fails when one test contradicts it at p < α / m, m "
    "its number of tests over all tasks (Bonferroni), and is inconclusive at this n otherwise; "
    "each cell shows the estimate that decided it with its 95 % interval. Intervals: "
    f"{BOOTSTRAP} seeded bootstrap resamples of the environments, seeds as replicates "
    "(cluster bootstrap); success: Wilson. Tests and assumptions: `docs/statistics.md`."
)


def claims_table(judged: list[Claim]) -> str:
    """One row per claim: the overall verdict and one per task."""
    tasks = sorted({t for c in judged for t in c.tasks})
    rows = [
        {"claim": c.name, "verdict": c.overall.cell()}
        | {f"T{t}": c.tasks[t].cell() if t in c.tasks else "" for t in tasks}
        for c in judged
    ]
    return markdown_table(pd.DataFrame.from_records(rows))


def reproduction_table(judged: dict[str, list[Claim]]) -> str:
    """Ours against the paper: a row per cell, a column per benchmark and criterion.

    ``judged``: the :func:`analysis.vs_paper.reproduction` of each benchmark by label.
    """
    keys = sorted({k for claims_ in judged.values() for c in claims_ for k in c.tasks})
    columns: dict[str, Claim] = {}
    for i, criterion in enumerate(MARGINS):
        for label, claims_ in judged.items():
            columns[f"{criterion.title}: {label}" if len(judged) > 1 else criterion.title] = (
                claims_[i]
            )
    rows = [{"cell": "all cells"} | {name: c.overall.cell() for name, c in columns.items()}]
    for key in keys:
        rows.append(
            {"cell": cell_label(key)}
            | {name: c.tasks[key].cell() if key in c.tasks else "" for name, c in columns.items()}
        )
    return markdown_table(pd.DataFrame.from_records(rows))


def verdict_sections(episodes: pd.DataFrame, paper: pd.DataFrame) -> list[str]:
    """The sections of ``fig5.md`` after the paired comparisons: intervals, seeds, verdicts."""
    parts = [
        "\n## The paper's claims as test verdicts\n",
        "Success at 0.03 m, the exact sum of squared accelerations. " + POLICY + "\n",
        claims_table(claims(episodes)),
    ]
    if set(PAPER_METHODS) & set(episodes.method):
        parts += [
            "\n## Ours against the paper (two-sample, the paper's n = 150)\n",
            "Equivalence within each margin: holds when the 95 % interval of the difference "
            "(or ratio) lies inside it, fails when it lies outside (Bonferroni over the cells); "
            "SE of the difference sqrt(SE_ours² + SE_paper²), the paper's SE its std / √150.\n",
            reproduction_table({"ours": reproduction(episodes, paper)}),
        ]
    parts += [
        "\n## Intervals (95 %)\n",
        "Per cell: seeds and environments (per seed), success with its Wilson interval, mean "
        "final time, its 2 std and the mean exact sum of squared accelerations with bootstrap "
        "intervals (seeds as replicates).\n",
        markdown_table(intervals(episodes)),
    ]
    spread = seed_spread(episodes)
    if len(spread):
        parts += [
            "\n## Seeds: pooled, within and between\n",
            "Cells that pooled several seeds (runs that differ only in `seed`). The seed means "
            "should scatter as the within-seed spread predicts (within 2 std / √n per seed); "
            "`seed effect p`: one-way ANOVA of the seed means.\n",
            markdown_table(spread),
        ]
    return parts
