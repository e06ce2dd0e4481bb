"""Fig. 5 of several benchmarks side by side: the paper, the authors' setup, ours, ablation steps.

``python -m analysis.compare [LABEL=DIR ...] [--out DIR]`` (``make table`` runs it with
``original=runs/paper_original ours=runs/paper`` when both exist; ``make ablation-table`` with the
ablation's steps), one benchmark configuration per ``DIR``. Writes ``compare.md``: per task and
method the success (at 0.03 m and 0.05 m), the final time and the sum of squared accelerations
(exact and as the paper computed it) for the paper and every benchmark, the same with a row per
benchmark, the paper's claims as test verdicts on each (as the paper counted and exactly, per
task) and each benchmark against the paper (:mod:`analysis.vs_paper`); ``docs/statistics.md``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pandas as pd

from amex.app.argparsing import OneLineParser
from amex.experiment.store import StoreError

from . import default_out, write_report
from .claims import claims
from .decide import Claim
from .episodes import TableError, load_runs
from .table import aggregate, benchmarks, paper_table
from .verdict_tables import POLICY, claims_table, reproduction_table
from .vs_paper import paper_claims, reproduction

DEFAULTS = (("original", Path("runs/paper_original")), ("ours", Path("runs/paper")))
PAPER_METHODS = ("amex", "dmp", "cr")


def paper_aggregate() -> pd.DataFrame:
    """The paper's Fig. 5 in the columns of :func:`analysis.table.aggregate` (150 each)."""
    p = paper_table()
    return pd.DataFrame(
        {
            "task": p.task,
            "method": p.method,
            "episodes": 150,
            "success": p.success,
            "final_time_mean": p.final_time_mean,
            "final_time_2std": p.final_time_2std,
            "sum_sq_acc_mean": p.sum_sq_acc_mean,
            "sum_sq_acc_paper_mean": p.sum_sq_acc_mean,
            "sum_sq_acc_t3_median": math.nan,
            "compute_time_mean": p.compute_time_mean,
        }
    )


def load(directory: Path) -> pd.DataFrame:
    """The episodes of the one benchmark configuration under ``directory``."""
    groups = benchmarks(load_runs(directory))
    if len(groups) != 1:
        raise TableError(
            f"{directory} holds {len(groups)} benchmark configurations; give one sweep's directory"
        )
    return groups[0].episodes


def _cell(df: pd.DataFrame, task: int, method: str, col: str, fmt: str) -> str:
    row = df[(df.task == task) & (df.method == method)]
    if not len(row) or col not in row or math.isnan(float(row[col].iloc[0])):
        return ""
    return f"{float(row[col].iloc[0]):{fmt}}"


def numbers(frames: dict[str, pd.DataFrame]) -> str:
    """The side-by-side table as Markdown."""
    labels = list(frames)
    measures = (
        ("success", "success", ".2f"),
        ("success 0.05 m", "success_005", ".2f"),
        ("final time [s]", "final_time_mean", ".2f"),
        ("2 std [s]", "final_time_2std", ".2f"),
        ("sum sq. acc. (paper's computation)", "sum_sq_acc_paper_mean", ".3g"),
        ("sum sq. acc. (exact)", "sum_sq_acc_mean", ".3g"),
    )
    head = ["task", "method"] + [f"{name}: {label}" for name, _, _ in measures for label in labels]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for task in (1, 2, 3, 4):
        for method in PAPER_METHODS:
            cells = [str(task), method]
            for _, col, fmt in measures:
                for label in labels:
                    df = frames[label]
                    if label == "paper" and col in ("success", "success_005", "sum_sq_acc_mean"):
                        # the paper's success was counted at 0.05 m; its sums as it computed them
                        col_here = "success" if col == "success_005" else ""
                        cells.append(_cell(df, task, method, col_here, fmt) if col_here else "")
                    else:
                        cells.append(_cell(df, task, method, col, fmt))
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: The measures of :func:`by_benchmark`: title, column, format.
MEASURES = (
    ("Success at 0.05 m (the paper's count)", "success_005", ".2f"),
    ("Mean final time [s]", "final_time_mean", ".2f"),
    ("Final time, 2 std [s]", "final_time_2std", ".2f"),
    ("Sum of squared accelerations as the paper computed it", "sum_sq_acc_paper_mean", ".3g"),
    ("Sum of squared accelerations, exact", "sum_sq_acc_mean", ".3g"),
)


def by_benchmark(frames: dict[str, pd.DataFrame], title: str, col: str, fmt: str) -> str:
    """One measure, a row per benchmark and a column per task and method, as Markdown."""
    head = ["benchmark"] + [f"T{t} {m}" for t in (1, 2, 3, 4) for m in PAPER_METHODS]
    lines = [f"### {title}\n", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label, df in frames.items():
        col_here = col
        if label == "paper":  # its success was counted at 0.05 m; its sums as it computed them
            col_here = {"success_005": "success", "sum_sq_acc_mean": ""}.get(col, col)
        cells = [
            _cell(df, t, m, col_here, fmt) if col_here else ""
            for t in (1, 2, 3, 4)
            for m in PAPER_METHODS
        ]
        lines.append("| " + " | ".join([label, *cells]) + " |")
    return "\n".join(lines) + "\n"


def judged(episodes: dict[str, pd.DataFrame]) -> dict[str, list[Claim]]:
    """The five claims on the paper and on every benchmark, as counted and exactly."""
    columns = {"paper": paper_claims(paper_table(), "sum_sq_acc_paper")}
    for label, df in episodes.items():
        columns[f"{label} (as the paper computed)"] = claims(df, "sum_sq_acc_paper", "success_005")
        columns[f"{label} (exact)"] = claims(df, "sum_sq_acc", "success")
    return columns


def verdicts(columns: dict[str, list[Claim]]) -> str:
    """The claims' overall verdicts, a column per benchmark and computation, as Markdown."""
    names = [c.name for c in columns["paper"]]
    for suffix in (", as the paper computed it", " (as the paper computed it)"):
        names = [n.replace(suffix, "") for n in names]
    head = ["claim", *columns]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i, name in enumerate(names):
        cells = [name] + [col[i].overall.cell() for col in columns.values()]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def per_task(columns: dict[str, list[Claim]]) -> list[str]:
    """The claims' verdicts per task, a table per benchmark and computation."""
    parts = []
    for label, judged_ in columns.items():
        parts += [f"\n### {label}\n", claims_table(judged_)]
    return parts


def _std_note(frames: dict[str, pd.DataFrame]) -> str:
    """Which standard deviation each benchmark's 2 std is (the runs' ``std_ddof``)."""
    kinds = {0: "over N (the population's)", 1: "over N - 1 (MATLAB's, as the paper)"}
    parts = [
        f"{label} {kinds.get(int(ddof), f'over N - {int(ddof)}')}"
        for label, df in frames.items()
        if "std_ddof" in df and len(df)
        for ddof in sorted(set(df.std_ddof))
    ]
    return f"2 std: {', '.join(parts)}." if parts else ""


def report(
    frames: dict[str, pd.DataFrame], episodes: dict[str, pd.DataFrame], sources: dict[str, Path]
) -> str:
    """The whole ``compare.md``: ``frames`` the aggregates (the paper's first), ``episodes``."""
    listed = ", ".join(f"{label} = `{path}`" for label, path in sources.items())
    columns = judged(episodes)
    paper = paper_table()
    repro = {label: reproduction(df, paper) for label, df in episodes.items()}
    return "\n".join(
        [
            "# Fig. 5 side by side\n",
            f"The paper (Englert & Toussaint 2014, Fig. 5) and {listed}. Means over the "
            "environments; the paper counted success at 0.05 m (its text says 0.03 m) and "
            "computed the sum of squared accelerations from joint angles rounded to 6 digits "
            f"(`sum_sq_acc_paper`). {_std_note(frames)}\n",
            numbers(frames),
            "\n## By benchmark\n",
            *(by_benchmark(frames, *m) for m in MEASURES),
            "## The paper's claims on each\n",
            verdicts(columns),
            "\n" + POLICY + " The paper's own numbers: two-sample tests on its printed means "
            "and std (unpaired: its environments are not published).\n",
            "## The claims per task\n",
            *per_task(columns),
            "\n## Each benchmark against the paper (two-sample, the paper's n = 150)\n",
            "Equivalence within each margin: holds when the 95 % interval of the difference "
            "(or ratio) lies inside it, fails when it lies outside (Bonferroni over the 12 "
            "cells); SE of the difference sqrt(SE_ours² + SE_paper²), the paper's SE its "
            "std / √150, ours the bootstrap's.\n",
            reproduction_table(repro),
            "",
        ]
    )


def _pair(text: str) -> tuple[str, Path]:
    label, sep, path = text.partition("=")
    if not sep or not label or not path:
        raise ValueError(text)
    return label, Path(path)


def main(argv: list[str] | None = None) -> int:
    """Command line (module notes)."""
    parser = OneLineParser(prog="analysis.compare", description=__doc__.splitlines()[0])
    parser.add_argument("benchmarks", nargs="*", metavar="LABEL=DIR")
    parser.add_argument("--out", default=default_out(), type=Path)
    parser.add_argument("--name", default="compare.md", help="output file name")
    args = parser.parse_args(argv)
    try:
        pairs = [_pair(b) for b in args.benchmarks] if args.benchmarks else list(DEFAULTS)
    except ValueError as e:
        parser.error(f"invalid benchmark {e}: valid: LABEL=DIR, e.g. original=runs/paper_original")
    sources = dict(pairs)
    try:
        episodes = {k: load(v) for k, v in sources.items()}
    except (TableError, StoreError) as e:
        print(f"analysis.compare: error: {e}", file=sys.stderr)
        return 2
    frames = {"paper": paper_aggregate(), **{k: aggregate(v) for k, v in episodes.items()}}
    text = report(frames, episodes, sources)
    path = write_report(args.out, args.name, text)
    print(text)
    print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
