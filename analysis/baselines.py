"""AMEX against today's reactive methods (issue #26): the comparison's tables, from its runs.

Usage::

    python -m analysis.baselines RUNS_DIR [--out DIR] [--robot R]  # conf/study/baselines.yaml
    python -m analysis.baselines --tuning DIR [DIR ...] [--out DIR]  # the tuning sweeps

The study's runs are ``RUNS_DIR/method=<m>,robot=<r>,task=<t>/episodes.csv`` (the robot is read
from the directory's name; ``panda`` when it names none). One file per robot, ``<robot>.md``,
with three tables:

* per task and method: environments, success with its Wilson 95 % interval
  (:func:`analysis.inference.success_interval`), final time (mean and std), the median
  ``sum_sq_acc``, ``plan_fidelity`` and ``min_clearance`` (and the smallest), the mean
  ``deadline_misses``, and the outer step's thread CPU time: the median over episodes of each
  episode's median step, and the 95th percentile over episodes of the same (per-step
  percentiles: ``make bench``);
* every method against AMEX (one row per task and metric, one column per method: the mean paired
  difference and "better", "worse" or "~"), and the pairs that isolate one factor
  (``amex_cbf`` - ``cbf_ik``:
  AMEX's plan adaptation behind the same filter; ``amex_cbf`` - ``amex``: the filter and joint
  targets; ``dmp_avoid`` - ``dmp``: the coupling term; ``rmpflow`` - ``cbf_ik``: metric-weighted
  avoidance against hard barriers): paired on the same environments, the mean difference a - b
  with its bootstrap 95 % interval (:func:`analysis.inference.resamples`), the exact McNemar test
  for success and the Wilcoxon signed-rank test otherwise; "a" or "b" names the better method
  when p < 0.05 / m, m the number of tests in that table (Bonferroni), else "-".

Methods of :data:`METHODS` without runs (``mppi`` before its runs exist) are left out and named
in a note. ``--tuning`` writes ``tuning.md``: per method and parameter cell, success per task,
their mean, the mean over tasks of the median ``sum_sq_acc`` and the mean deadline misses, and
the cell the rule of ``conf/study/tuning_<method>.yaml`` chooses (:func:`choose`).
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from amex.app.argparsing import OneLineParser
from amex.experiment.store import StoreError

from . import default_out
from .episodes import TableError, read_episodes
from .inference import ALPHA, mcnemar_p, mean_interval, resamples, success_interval, wilcoxon
from .markdown import markdown_table

#: The study's methods in the tables' order (conf/study/baselines.yaml).
METHODS = ("amex", "dmp", "cr", "rmpflow", "dmp_avoid", "cbf_ik", "amex_cbf", "mppi")
ROBOTS = ("panda", "ur5", "chain7")
#: The pairs that isolate one factor (module notes), a - b.
FACTOR_PAIRS = (
    ("amex_cbf", "cbf_ik"),
    ("amex_cbf", "amex"),
    ("dmp_avoid", "dmp"),
    ("rmpflow", "cbf_ik"),
)
#: Paired metrics and the sign of "better" (+1: larger is better).
PAIRED = (
    ("success", +1),
    ("final_time", -1),
    ("sum_sq_acc", -1),
    ("plan_fidelity", -1),
    ("min_clearance", +1),
)
NUMERIC = ("deadline_misses", "min_clearance", "plan_fidelity", "final_axis_error", "path_length")
_ROBOT = re.compile(r"(?:^|,)robot=([A-Za-z0-9_]+)")


def robot_of(path: str | Path) -> str:
    """The robot a run's directory names (``robot=<name>``), ``panda`` if none."""
    m = _ROBOT.search(Path(path).parent.name)
    return m.group(1) if m else "panda"


def load_study(root: Path) -> pd.DataFrame:
    """Every episode under ``root`` with a ``robot`` column (module notes).

    Raises:
        TableError: no such directory or no episodes under it.
    """
    if not root.is_dir():
        raise TableError(f"{root}: no such directory (run amex-run -m study=baselines first)")
    files = sorted(root.rglob("episodes.csv"))
    if not files:
        raise TableError(f"no episodes.csv under {root} (run amex-run -m study=baselines first)")
    df = read_episodes(files, f"every episodes.csv under {root} is empty")
    df["robot"] = [robot_of(f) for f in df.file]
    for col in NUMERIC:
        df[col] = pd.to_numeric(df[col], errors="coerce") if col in df else math.nan
    return df


def _fmt(x: float, digits: int = 3) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{digits}g}"


def _us(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x * 1e6:.0f}"


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """The per-task, per-method table of one robot (module notes)."""
    rows = []
    for task in sorted(df.task.unique()):
        sub = df[df.task == task]
        for method in (m for m in METHODS if m in set(sub.method)):
            e = sub[sub.method == method]
            ok = e.success.to_numpy()
            ci = success_interval(ok, e.seed.to_numpy())
            cpu = e.compute_cpu_median.astype(float).dropna()
            clear = e.min_clearance.dropna()
            rows.append(
                {
                    "task": int(task),
                    "method": method,
                    "n": len(e),
                    "success [95% CI]": f"{ci.estimate:.2f} [{ci.low:.2f}, {ci.high:.2f}]",
                    "final time [s]": f"{e.final_time.mean():.2f} ± {e.final_time.std(ddof=1):.2f}"
                    if len(e) > 1
                    else f"{e.final_time.mean():.2f}",
                    "sum_sq_acc (median)": _fmt(float(e.sum_sq_acc.median())),
                    "plan_fidelity [m] (median)": _fmt(float(e.plan_fidelity.median())),
                    "min_clearance [m] (median, min)": "-"
                    if clear.empty
                    else f"{float(clear.median()):.3f}, {float(clear.min()):.3f}",
                    "deadline misses": _fmt(float(e.deadline_misses.mean()), 2),
                    "step CPU [us] (median, p95)": "-"
                    if cpu.empty
                    else f"{_us(float(cpu.median()))}, {_us(float(np.percentile(cpu, 95)))}",
                }
            )
    return pd.DataFrame.from_records(rows)


def paired_rows(df: pd.DataFrame, pairs: Sequence[tuple[str, str]]) -> list[dict]:
    """Paired tests of ``pairs`` (a - b) on every task and metric of :data:`PAIRED`."""
    out = []
    for task in sorted(df.task.unique()):
        sub = df[df.task == task]
        present = set(sub.method)
        for a, b in pairs:
            if a not in present or b not in present:
                continue
            both = sub[sub.method.isin([a, b])]
            wide = both.pivot(index=["seed", "env"], columns="method")
            for metric, sign in PAIRED:
                pair = wide[[(metric, a), (metric, b)]].astype(float).dropna()
                if len(pair) < 2:
                    continue
                va, vb = pair[(metric, a)].to_numpy(), pair[(metric, b)].to_numpy()
                d = va - vb
                ci = mean_interval(d, resamples(pair.index.get_level_values("seed").to_numpy()))
                p = mcnemar_p(va > 0.5, vb > 0.5) if metric == "success" else wilcoxon(d)[0]
                out.append(
                    {
                        "task": int(task),
                        "a": a,
                        "b": b,
                        "metric": metric,
                        "sign": sign,
                        "pairs": len(d),
                        "diff": ci.estimate,
                        "low": ci.low,
                        "high": ci.high,
                        "p": p,
                    }
                )
    return out


def paired_table(records: list[dict]) -> pd.DataFrame:
    """``records`` as a table with the better method at the Bonferroni level (module notes)."""
    m = max(len(records), 1)
    rows = []
    for r in records:
        better = "-"
        if r["p"] < ALPHA / m and r["diff"] != 0:
            better = r["a"] if r["diff"] * r["sign"] > 0 else r["b"]
        rows.append(
            {
                "task": r["task"],
                "a - b": f"{r['a']} - {r['b']}",
                "metric": r["metric"],
                "pairs": r["pairs"],
                "mean diff [95% CI]": f"{r['diff']:.3g} [{r['low']:.3g}, {r['high']:.3g}]",
                "test": "mcnemar" if r["metric"] == "success" else "wilcoxon",
                "p": f"{r['p']:.2g}",
                "better": better,
            }
        )
    return pd.DataFrame.from_records(rows)


def against_table(records: list[dict], reference: str = "amex") -> pd.DataFrame:
    """Every method against ``reference``: one row per task and metric, one column per method.

    A cell is the mean paired difference (method - reference) and ``better`` or ``worse`` when
    its test's p is below 0.05 / m (m: the tests in the table, Bonferroni), else ``~``.
    """
    m = max(len(records), 1)
    methods = list(dict.fromkeys(r["a"] for r in records))
    cells: dict[tuple[int, str], dict[str, str]] = {}
    for r in records:
        word = "~"
        if r["p"] < ALPHA / m and r["diff"] != 0:
            word = "better" if r["diff"] * r["sign"] > 0 else "worse"
        key = (r["task"], r["metric"])
        cells.setdefault(key, {})[r["a"]] = f"{r['diff']:.3g} {word}"
    order = [metric for metric, _ in PAIRED]
    rows = []
    for task, metric in sorted(cells, key=lambda k: (k[0], order.index(k[1]))):
        row = {"task": task, "metric": f"{metric} (- {reference})"}
        row.update({method: cells[(task, metric)].get(method, "-") for method in methods})
        rows.append(row)
    return pd.DataFrame.from_records(rows)


def robot_report(df: pd.DataFrame, robot: str) -> str:
    """The three tables of one robot (module notes) as Markdown."""
    present = [m for m in METHODS if m in set(df.method)]
    missing = [m for m in METHODS if m not in present]
    envs = sorted(df.groupby(["task", "method"]).size().unique())
    lines = [
        f"# AMEX against today's reactive methods: {robot}",
        "",
        "Generated by `python -m analysis.baselines` from the study's runs "
        f"(seed {', '.join(str(s) for s in sorted(df.seed.unique()))}, "
        f"{'/'.join(str(n) for n in envs)} environments per cell).",
    ]
    if missing:
        lines += ["", f"Not in the runs (left out): {', '.join(missing)}."]
    lines += ["", "## Per task and method", "", markdown_table(summary(df)), ""]
    against = [(m, "amex") for m in present if m != "amex"]
    records = paired_rows(df, against) if "amex" in present else []
    lines += ["## Every method against AMEX", ""]
    if records:
        lines += [markdown_table(against_table(records)), ""]
    else:
        lines += ["(AMEX, or every other method, is not in the runs)", ""]
    factors = [p for p in FACTOR_PAIRS if p[0] in present and p[1] in present]
    lines += ["## The pairs that isolate one factor", ""]
    if factors:
        lines += [markdown_table(paired_table(paired_rows(df, factors))), ""]
    else:
        lines += ["(none of the pairs has both methods in the runs)", ""]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- tuning
def cell_of(path: str | Path) -> str:
    """A tuning run's parameter cell: its directory's swept values without method and task."""
    parts = Path(path).parent.name.split(",")
    keep = [p for p in parts if not p.startswith(("method=", "task="))]
    return ",".join(p.removeprefix("method.") for p in keep) or "(defaults)"


def choose(cells: pd.DataFrame) -> str:
    """The tuning rule: the highest mean success; within one episode of it (1/40), the lowest
    mean of the median sum_sq_acc; ties: the first cell in order (``cells`` in sweep order)."""
    best = cells["mean success"].max()
    near = cells[cells["mean success"] >= best - 1.0 / 40 - 1e-12]
    return str(near.sort_values("mean sum_sq_acc", kind="stable").iloc[0]["cell"])


def tuning_report(roots: Sequence[Path]) -> str:
    """The tuning table (module notes) of the sweeps under ``roots``."""
    tables = []
    for root in roots:
        files = sorted(root.rglob("episodes.csv"))
        if not files:
            raise TableError(f"no episodes.csv under {root} (run its tuning study first)")
        df = read_episodes(files)
        df["cell"] = [cell_of(f) for f in df.file]
        df["deadline_misses"] = pd.to_numeric(df.deadline_misses, errors="coerce")
        for method in sorted(df.method.unique()):
            e = df[df.method == method]
            rows = []
            for cell in dict.fromkeys(e.cell):  # first appearance: the sweep's order
                c = e[e.cell == cell]
                by_task = c.groupby("task")
                row = {"method": method, "cell": cell}
                for task, t in by_task:
                    row[f"task {task}"] = f"{t.success.mean():.2f}"
                row["mean success"] = float(by_task.success.mean().mean())
                row["mean sum_sq_acc"] = float(by_task.sum_sq_acc.median().mean())
                row["deadline misses"] = float(c.deadline_misses.mean())
                row["n"] = len(c)
                rows.append(row)
            cells = pd.DataFrame.from_records(rows)
            chosen = choose(cells)
            cells["chosen"] = ["yes" if c == chosen else "" for c in cells.cell]
            cells["mean success"] = cells["mean success"].map(lambda v: f"{v:.3f}")
            cells["mean sum_sq_acc"] = cells["mean sum_sq_acc"].map(lambda v: f"{v:.4g}")
            cells["deadline misses"] = cells["deadline misses"].map(lambda v: f"{v:.3f}")
            tables.append(cells)
    table = pd.concat(tables, ignore_index=True).fillna("-")
    return "\n".join(
        [
            "# The reactive methods' tuning (seed 1)",
            "",
            "Generated by `python -m analysis.baselines --tuning` from the tuning sweeps "
            "(conf/study/tuning_<method>.yaml).",
            "",
            markdown_table(table),
            "",
        ]
    )


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(text)
    tmp.replace(path)
    print(f"wrote {path}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Command line (module notes)."""
    parser = OneLineParser(prog="analysis.baselines", description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="*", type=Path, help="the study's runs (or tuning sweeps)")
    parser.add_argument("--tuning", action="store_true", help="the runs are tuning sweeps")
    parser.add_argument("--out", default=default_out(), type=Path)
    parser.add_argument("--robot", choices=ROBOTS, help="only this robot's file")
    args = parser.parse_args(argv)
    if not args.runs:
        parser.error("no runs given; valid: a directory of the study's runs (runs/baselines)")
    try:
        if args.tuning:
            _write(args.out / "tuning.md", tuning_report(args.runs))
            return 0
        if len(args.runs) != 1:
            parser.error(f"{len(args.runs)} directories; valid: one (the study's) without --tuning")
        df = load_study(args.runs[0])
    except (TableError, StoreError) as e:
        print(f"analysis.baselines: error: {e}", file=sys.stderr)
        return 2
    robots = [args.robot] if args.robot else [r for r in ROBOTS if r in set(df.robot)]
    for robot in robots:
        _write(args.out / f"{robot}.md", robot_report(df[df.robot == robot], robot))
    return 0


if __name__ == "__main__":
    sys.exit(main())
