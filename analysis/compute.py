"""The compute claim "CR >> AMEX > DMP" across reruns: CPU time beside wall time.

``python -m analysis.compute [LABEL=]DIR ... [--out DIR]`` (``make table`` runs it on every
directory under ``runs/compute/``), one benchmark per ``DIR``: reruns of the same cells, e.g. one
on a quiet machine and one beside another heavy job. Writes ``compute.md``:

* per rerun, task and method the median over the environments of each episode's median step
  time, on the thread's CPU time (``compute_cpu_median``) and on the wall clock;
* per rerun and task the ratios CR / AMEX and AMEX / DMP of those medians with their bootstrap
  95 % intervals (:mod:`analysis.claims`, seeds as replicates) and the claim's verdict;
* across reruns the range of each median and ratio, and whether the verdicts agree.

A ratio is what the same Python process spends per outer step, not the paper's C++: it says how
the methods' costs compare in this implementation (``docs/statistics.md``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from amex.app.argparsing import OneLineParser
from amex.experiment.store import StoreError

from . import default_out, write_report
from .claims import PAPER_METHODS, claim_names, compute_claim
from .episodes import TableError
from .markdown import markdown_table

MEASURES = (("compute_cpu_median", "CPU"), ("compute_time_median", "wall"))


def medians(episodes: pd.DataFrame) -> pd.DataFrame:
    """Per task and method the median step time on each measure [s] (NaN: not recorded)."""
    rows = []
    for (task, method), g in episodes.groupby(["task", "method"]):
        if method not in PAPER_METHODS or task < 1:
            continue
        row = {"task": int(task), "method": method, "n": len(g)}
        for column, name in MEASURES:
            values = g[column].astype(float) if column in g else pd.Series([np.nan])
            row[name] = float(values.median()) if values.notna().all() else np.nan
        rows.append(row)
    out = pd.DataFrame.from_records(rows)
    if len(out):
        out["_rank"] = out.method.map(lambda m: PAPER_METHODS.index(m))
        out = out.sort_values(["task", "_rank"]).drop(columns="_rank").reset_index(drop=True)
    return out


def ratios(episodes: pd.DataFrame, column: str) -> dict[int, list]:
    """Per task the compute claim's two tests on ``column`` (:func:`compute_claim`)."""
    out = {}
    for task in sorted(int(t) for t in episodes.task.unique() if t >= 1):
        tests = compute_claim(episodes[episodes.task == task], column)
        if tests:
            out[task] = tests
    return out


def report(reruns: dict[str, pd.DataFrame], sources: dict[str, Path]) -> str:
    """The whole ``compute.md``."""
    from .decide import decide

    listed = ", ".join(f"{label} = `{path}`" for label, path in sources.items())
    parts = [
        "# Compute time across reruns\n",
        f"Reruns {listed}. Median over the environments of each episode's median outer-step "
        "time [s]: thread CPU time and wall time. Ratios of those medians with bootstrap 95 % "
        "intervals; the claim holds when CR / AMEX > 10 and AMEX / DMP > 1 on every task "
        "(`docs/statistics.md`).\n",
        "## Median step time [s]\n",
    ]
    table = None
    for label, df in reruns.items():
        m = medians(df).rename(columns={"CPU": f"CPU: {label}", "wall": f"wall: {label}"})
        m = m.drop(columns="n")
        table = m if table is None else table.merge(m, on=["task", "method"], how="outer")
    if table is not None:
        shown = table.copy()
        for col in shown.columns[2:]:
            shown[col] = shown[col].map(lambda v: "" if np.isnan(v) else f"{v:.3g}")
        for name in ("CPU", "wall"):
            cols = [c for c in table.columns if c.startswith(f"{name}: ")]
            spread = table[cols].max(axis=1) / table[cols].min(axis=1)
            shown[f"{name} max/min"] = spread.map(lambda v: "" if np.isnan(v) else f"{v:.2f}")
        parts.append(markdown_table(shown))
    name = claim_names("sum_sq_acc")[3]
    rows = []
    verdicts = {}
    for label, df in reruns.items():
        for column, measure in MEASURES:
            per_task = ratios(df, column)
            if not per_task:
                continue
            claim = decide(name, per_task)
            verdicts[(label, measure)] = claim.overall.word
            for task, tests in per_task.items():
                rows.append(
                    {
                        "rerun": label,
                        "measure": measure,
                        "task": task,
                        "CR/AMEX": tests[0].text,
                        "AMEX/DMP": tests[1].text,
                        "task verdict": claim.tasks[task].word,
                        "claim": claim.overall.word,
                    }
                )
    parts += ["\n## Ratios and verdicts per rerun\n", markdown_table(pd.DataFrame(rows))]
    agree = []
    for measure in ("CPU", "wall"):
        words = {label: w for (label, m), w in verdicts.items() if m == measure}
        if words:
            same = "yes" if len(set(words.values())) == 1 else "no"
            agree.append({"measure": measure} | words | {"the same on every rerun": same})
    parts += ["\n## Do the reruns agree?\n", markdown_table(pd.DataFrame(agree))]
    return "\n".join(parts) + "\n"


def _source(text: str) -> tuple[str, Path]:
    label, sep, path = text.partition("=")
    return (label, Path(path)) if sep else (Path(text).name, Path(text))


def main(argv: list[str] | None = None) -> int:
    """Command line (module notes)."""
    from .compare import load

    parser = OneLineParser(prog="analysis.compute", description=__doc__.splitlines()[0])
    parser.add_argument("reruns", nargs="+", metavar="[LABEL=]DIR")
    parser.add_argument("--out", default=default_out(), type=Path)
    args = parser.parse_args(argv)
    sources = dict(_source(r) for r in args.reruns)
    try:
        reruns = {label: load(path) for label, path in sources.items()}
    except (TableError, StoreError) as e:
        print(f"analysis.compute: error: {e}", file=sys.stderr)
        return 2
    text = report(reruns, sources)
    path = write_report(args.out, "compute.md", text)
    print(text)
    print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
