"""Markdown tables of the reports: a DataFrame as a pipe table, and the paired comparisons."""

from __future__ import annotations

import pandas as pd

#: The columns of a paired comparison as the reports show them (see :func:`paired_markdown`).
PAIRED_COLUMNS = ("task", "a", "b", "metric", "pairs", "mean_diff", "95% CI", "test", "p")


def markdown_table(df: pd.DataFrame) -> str:
    """``df`` as a GitHub pipe table: one header row, one row per row, cells as ``str(value)``."""
    cols = list(df.columns)
    lines = ["| " + " | ".join(str(c) for c in cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(str(v) for v in row) + " |")
    return "\n".join(lines)


def paired_markdown(pairs: pd.DataFrame) -> str:
    """Paired comparisons (rows of :func:`analysis.comparisons.paired`) as a table.

    The mean difference and its bootstrap interval to 3 significant digits, the paired test
    (Wilcoxon signed-rank, or McNemar for success) and its p to 2.
    """
    shown = pairs.copy()
    shown["mean_diff"] = pairs.mean_diff.map(lambda v: f"{v:.3g}")
    shown["95% CI"] = [
        f"[{lo:.3g}, {hi:.3g}]" for lo, hi in zip(pairs.ci_low, pairs.ci_high, strict=True)
    ]
    shown["p"] = pairs.p.map(lambda v: f"{v:.2g}")
    return markdown_table(shown[list(PAIRED_COLUMNS)])
