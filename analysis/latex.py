"""Fig. 5 as LaTeX that fits one column of a two-column paper (booktabs, two tables).

Table (a): success at 0.03 m and final time; table (b): sum of squared accelerations and compute
time per outer step [ms]; each with the paper's values beside ours, mean ± 2 std as in Fig. 5.
Numbers outside [1e-3, 1e4) are written as ``a·10^k`` in math mode (``docs/analysis.md``).
"""

from __future__ import annotations

import math

import pandas as pd

from amex.core.palette import method_label

HEADER = "% Fig. 5 reproduced by amex (make table); needs \\usepackage{booktabs}\n"


def sci(value: float, digits: int = 2) -> str:
    """``value`` to ``digits`` significant digits: plain in [1e-3, 1e4), else ``a·10^k``."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "--"
    if value == 0:
        return "0"
    k = math.floor(math.log10(abs(value)))
    if -3 <= k < 4:
        return f"{value:.{max(digits - 1 - k, 0)}f}"
    return f"${value / 10**k:.{digits - 1}f}{{\\cdot}}10^{{{k}}}$"


def pm(mean: float, two_std: float, fmt=sci) -> str:
    """``mean ± two_std``, ``--`` for a missing value."""
    if mean is None or (isinstance(mean, float) and math.isnan(mean)):
        return "--"
    return f"{fmt(mean)}\\,$\\pm$\\,{fmt(two_std)}"


def _rows(merged: pd.DataFrame, cells) -> list[str]:
    lines = []
    last_task = None
    for r in merged.itertuples():
        if last_task is not None and r.task != last_task:
            lines.append("\\midrule")
        task = str(r.task) if r.task != last_task else ""
        last_task = r.task
        name = method_label(str(r.method)).replace("#", "\\#").replace("_", "\\_")
        lines.append(" & ".join([task, name, *cells(r)]) + " \\\\")
    return lines


def _table(caption: str, label: str, columns: str, head: list[str], body: list[str]) -> str:
    return "\n".join(
        [
            "\\begin{table}[t]",
            "\\centering\\footnotesize",
            "\\setlength{\\tabcolsep}{2pt}",
            f"\\caption{{{caption}}}",
            f"\\label{{{label}}}",
            f"\\begin{{tabular}}{{{columns}}}",
            "\\toprule",
            *head,
            "\\midrule",
            *body,
            "\\bottomrule",
            "\\end{tabular}",
            "\\end{table}",
            "",
        ]
    )


def fig5_latex(ours: pd.DataFrame, paper: pd.DataFrame) -> str:
    """The two column-wide tables for :func:`analysis.table.aggregate`'s output."""
    merged = ours.merge(paper, on=["task", "method"], how="left", suffixes=("", "_paper"))
    n = f"{int(merged.episodes.min())}" if len(merged) else "0"
    if len(merged) and merged.episodes.min() != merged.episodes.max():
        n = f"{int(merged.episodes.min())}-{int(merged.episodes.max())}"

    def success(r) -> str:
        paper_value = "" if math.isnan(r.success_paper) else f" ({r.success_paper:.2f})"
        return f"{r.success:.2f}{paper_value}"

    a = _table(
        f"Success at 0.03\\,m and final time (mean\\,$\\pm$\\,2\\,std over {n} environments; "
        "the paper's Fig.~5 in parentheses and beside ours).",
        "tab:fig5-success",
        "llccc",
        [
            "Task & Method & Success & \\multicolumn{2}{c}{Final time [s]} \\\\",
            "\\cmidrule(lr){4-5}",
            " & & ours (paper) & ours & paper \\\\",
        ],
        _rows(
            merged,
            lambda r: [
                success(r),
                pm(r.final_time_mean, r.final_time_2std, lambda v: f"{v:.2f}"),
                pm(r.final_time_mean_paper, r.final_time_2std_paper, lambda v: f"{v:.2f}"),
            ],
        ),
    )
    b = _table(
        "Sum of squared joint accelerations [$10^3$\\,rad$^2$/s$^4$] and compute time per outer "
        "step [ms] (mean\\,$\\pm$\\,2\\,std; the paper's Fig.~5 beside ours).",
        "tab:fig5-smoothness",
        "llcccc",
        [
            "Task & Method & \\multicolumn{2}{c}{Sum sq.\\ acc.\\ [$10^3$]} & "
            "\\multicolumn{2}{c}{Compute [ms]} \\\\",
            "\\cmidrule(lr){3-4}\\cmidrule(lr){5-6}",
            " & & ours & paper & ours & paper \\\\",
        ],
        _rows(
            merged,
            lambda r: [
                pm(r.sum_sq_acc_mean / 1e3, r.sum_sq_acc_2std / 1e3),
                pm(r.sum_sq_acc_mean_paper / 1e3, r.sum_sq_acc_2std_paper / 1e3),
                pm(r.compute_time_mean * 1e3, r.compute_time_2std * 1e3),
                pm(r.compute_time_mean_paper * 1e3, r.compute_time_2std_paper * 1e3),
            ],
        ),
    )
    return HEADER + a + "\n" + b
