"""``make table``: the paper's Fig. 5 from our runs, the paper's numbers beside ours, paired stats.

Reads every ``episodes.csv`` under a directory (default ``runs/``), checks that they come from one
benchmark (equal scene hashes: identical environments for every method) and that no (task, method)
appears with two configurations, then writes into ``analysis/out/``:

* ``fig5.md`` / ``fig5.tex`` / ``fig5.csv``: per task and method, success (0.03 m), success at
  0.05 m, collisions, final time, sum of squared accelerations and compute time as mean ± 2 std,
  with the paper's Fig. 5 row beside ours;
* ``paired.csv`` and a section of ``fig5.md``: paired comparisons on identical environments (AMEX vs
  DMP, AMEX vs CR, AMEX vs DMP with phase stopping, DMP vs CR, and any other method, e.g. a
  plugin, against AMEX, DMP and CR): mean difference with a bootstrap 95 % interval and the
  Wilcoxon signed-rank p-value;
* the paper's qualitative claims, each marked holds / fails / n/a in ``fig5.md``, plus one
  diagnostic: smoothness at equal duration (:func:`duration_invariant_smoothness`).

Errors (no runs, a corrupt or truncated csv, mixed configurations) print one line naming the file
and exit with code 2; the outputs are replaced only when everything succeeded.

Usage: ``python -m analysis.table [RUNS_DIR] [--out DIR]``.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from amex.argparsing import OneLineParser
from amex.errors import AmexError
from amex.store import HASH_COLUMNS, StoreError, parse_result, read_rows

HERE = Path(__file__).resolve().parent
PAPER_CSV = HERE / "paper_fig5.csv"
METHOD_ORDER = ("amex", "dmp", "dmp_ps", "cr", "track")
PAIRS = (("amex", "dmp"), ("amex", "cr"), ("amex", "dmp_ps"), ("dmp", "cr"))
PAIRED_METRICS = ("success", "final_time", "sum_sq_acc", "sum_sq_acc_t3")
BOOTSTRAP = 10_000


class TableError(AmexError):
    """The runs cannot make one table; the message names the file(s)."""


def load_runs(root: Path) -> pd.DataFrame:
    """All episodes under ``root`` as one DataFrame (a row per episode), checked for consistency."""
    if not root.is_dir():
        raise TableError(f"{root}: no such directory (run amex-run first, or RUNS=DIR)")
    files = sorted(root.rglob("episodes.csv"))
    if not files:
        raise TableError(f"no episodes.csv under {root} (run amex-run first, or RUNS=DIR)")
    frames = []
    for path in files:
        rows = read_rows(path)
        if not rows:
            continue
        if "scene_hash" not in rows[0]:
            raise TableError(f"{path}: written by an older amex without configuration hashes")
        # typed by the store's own parser, as the resume reads them (read_rows checked every row)
        typed = [{**parse_result(r).as_row(), **{h: r[h] for h in HASH_COLUMNS}} for r in rows]
        frame = pd.DataFrame(typed)
        frame["file"] = str(path)
        frames.append(frame)
    if not frames:
        raise TableError(f"every episodes.csv under {root} is empty")
    df = pd.concat(frames, ignore_index=True)
    scenes = df.groupby("scene_hash")["file"].first()
    if len(scenes) > 1:
        a, b = scenes.iloc[0], scenes.iloc[1]
        raise TableError(
            f"runs of different benchmark configurations are mixed: {a} and {b} "
            f"(scene hash {scenes.index[0]} vs {scenes.index[1]}); point RUNS at one sweep"
        )
    configs = df.groupby(["task", "method"])["config_hash"].nunique()
    mixed = configs[configs > 1]
    if len(mixed):
        task, method = mixed.index[0]
        files_of = df[(df.task == task) & (df.method == method)].groupby("config_hash")["file"]
        a, b = files_of.first().iloc[:2]
        raise TableError(f"task {task} {method} ran with two configurations: {a} and {b}")
    df = df.drop_duplicates(subset=["task", "method", "env"], keep="first")
    for col in ("task", "env", "seed"):
        df[col] = df[col].astype(int)
    for col in ("success", "success_005", "collided"):
        df[col] = df[col].astype(int).astype(bool)
    for col in (
        "final_distance",
        "final_time",
        "sum_sq_acc",
        "compute_time_median",
        "compute_time_mean",
    ):
        df[col] = df[col].astype(float)
    df["sum_sq_acc_t3"] = duration_invariant_smoothness(df.sum_sq_acc, df.final_time)
    return df


def duration_invariant_smoothness(sum_sq_acc, final_time):
    """``sum_sq_acc * final_time**3``: the sum of squared accelerations at equal duration.

    Executing a motion k times slower divides its accelerations by k^2 and multiplies the number
    of 1 kHz samples by k, so the sum of squared accelerations falls as k^-3 while this product
    stays the same. It separates "smoother" from "slower": a method whose adaptive phase stretches
    the motion (AMEX) scores lower on ``sum_sq_acc`` for that reason alone. A diagnostic, not one
    of the paper's metrics; episodes that stall until ``max_time`` inflate it, so the table reports
    its median. Units rad^2 s^-1 (no dt factor in ``sum_sq_acc``).
    """
    return sum_sq_acc * final_time**3


def _mean_2std(values: pd.Series) -> tuple[float, float]:
    a = values.to_numpy(dtype=float)
    return float(a.mean()), float(2.0 * a.std())


def aggregate(df: pd.DataFrame) -> pd.DataFrame:
    """Fig. 5 per (task, method): means and 2 std, our definitions (:mod:`amex.metrics`)."""
    records = []
    for (task, method), g in df.groupby(["task", "method"]):
        ft, ft2 = _mean_2std(g.final_time)
        acc, acc2 = _mean_2std(g.sum_sq_acc)
        ct, ct2 = _mean_2std(g.compute_time_mean)
        records.append(
            {
                "task": task,
                "method": method,
                "episodes": len(g),
                "success": g.success.mean(),
                "success_005": g.success_005.mean(),
                "collided": g.collided.mean(),
                "failures": int((g.failure != "").sum()),
                "final_time_mean": ft,
                "final_time_2std": ft2,
                "sum_sq_acc_mean": acc,
                "sum_sq_acc_2std": acc2,
                "sum_sq_acc_t3_median": float(g.sum_sq_acc_t3.median()),
                "compute_time_mean": ct,
                "compute_time_2std": ct2,
                "compute_time_median": float(g.compute_time_median.median()),
            }
        )
    out = pd.DataFrame.from_records(records)
    rank = {m: i for i, m in enumerate(METHOD_ORDER)}
    out["_rank"] = out.method.map(lambda m: rank.get(m, len(rank)))
    return out.sort_values(["task", "_rank", "method"]).drop(columns="_rank").reset_index(drop=True)


def paper_table() -> pd.DataFrame:
    """The paper's Fig. 5 as data."""
    return pd.read_csv(PAPER_CSV, comment="#")


def bootstrap_ci(d: np.ndarray, seed: int = 0, n: int = BOOTSTRAP) -> tuple[float, float]:
    """95 % percentile bootstrap interval of the mean of ``d`` (seeded: reproducible)."""
    rng = np.random.default_rng(seed)
    means = rng.choice(d, size=(n, len(d)), replace=True).mean(axis=1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return float(lo), float(hi)


def paired(df: pd.DataFrame) -> pd.DataFrame:
    """Paired comparisons (method a minus method b) on the environments both ran."""
    from scipy.stats import wilcoxon

    records = []
    methods = set(df.method)
    others = sorted(methods - set(METHOD_ORDER))  # e.g. plugin methods: each against the paper's
    pairs = [*PAIRS, *((m, b) for m in others for b in ("amex", "dmp", "cr"))]
    for task in sorted(df.task.unique()):
        sub = df[df.task == task]
        for a, b in pairs:
            if a not in methods or b not in methods:
                continue
            wide = sub[sub.method.isin([a, b])].pivot(index="env", columns="method")
            wide = wide.dropna()
            if len(wide) < 2:
                continue
            for metric in PAIRED_METRICS:
                d = (wide[(metric, a)].astype(float) - wide[(metric, b)].astype(float)).to_numpy()
                lo, hi = bootstrap_ci(d, seed=task)
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


def claims(ours: pd.DataFrame) -> list[tuple[str, str, str]]:
    """The paper's qualitative claims checked on our aggregates: (claim, verdict, evidence)."""
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
        out.append((name, "holds" if ok else "fails", evidence))

    present = tuple(m for m in paper_methods if m in have)
    verdict(
        "all methods above 0.9 success",
        present or paper_methods,
        lambda t: all(get(t, m, "success") > 0.9 for m in present),
        lambda t: ", ".join(f"{m} {get(t, m, 'success'):.2f}" for m in present),
    )
    for claim, col in (
        ("CR is the smoothest (lowest sum of squared accelerations)", "sum_sq_acc_mean"),
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
        "AMEX is smoother than DMP",
        ("amex", "dmp"),
        lambda t: get(t, "amex", "sum_sq_acc_mean") < get(t, "dmp", "sum_sq_acc_mean"),
        lambda t: (
            f"amex {get(t, 'amex', 'sum_sq_acc_mean'):.3g} vs dmp "
            f"{get(t, 'dmp', 'sum_sq_acc_mean'):.3g}"
        ),
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


def _pm(mean: float, two_std: float, fmt: str) -> str:
    if math.isnan(mean):
        return ""
    return f"{mean:{fmt}} ± {two_std:{fmt}}"


def combined(ours: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Ours and the paper's rows side by side, as display strings."""
    merged = ours.merge(paper, on=["task", "method"], how="left", suffixes=("", "_paper"))
    rows = []
    for r in merged.itertuples():
        rows.append(
            {
                "task": r.task,
                "method": r.method,
                "n": r.episodes,
                "success": f"{r.success:.2f}",
                "success (paper)": "" if math.isnan(r.success_paper) else f"{r.success_paper:.2f}",
                "success 0.05 m": f"{r.success_005:.2f}",
                "collided": f"{r.collided:.2f}",
                "final time [s]": _pm(r.final_time_mean, r.final_time_2std, ".2f"),
                "final time (paper)": _pm(r.final_time_mean_paper, r.final_time_2std_paper, ".2f"),
                "sum sq. acc.": _pm(r.sum_sq_acc_mean, r.sum_sq_acc_2std, ".2e"),
                "sum sq. acc. (paper)": _pm(
                    r.sum_sq_acc_mean_paper, r.sum_sq_acc_2std_paper, ".2e"
                ),
                "compute [s]": _pm(r.compute_time_mean, r.compute_time_2std, ".2e"),
                "compute (paper)": _pm(r.compute_time_mean_paper, r.compute_time_2std_paper, ".2e"),
                "compute median [s]": f"{r.compute_time_median:.2e}",
                "sum sq. acc. x T^3 (median)": f"{r.sum_sq_acc_t3_median:.2e}",
            }
        )
    return pd.DataFrame.from_records(rows)


def _markdown(df: pd.DataFrame) -> str:
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in df.itertuples(index=False):
        lines.append("| " + " | ".join(str(v) for v in row) + " |")
    return "\n".join(lines)


def render_markdown(table: pd.DataFrame, pairs: pd.DataFrame, verdicts, source: Path) -> str:
    """The whole report as Markdown."""
    parts = [
        f"# Fig. 5, reproduced (from `{source}`)\n",
        "Mean ± 2 std over the environments of each run; the paper's numbers (Englert & "
        "Toussaint 2014, Fig. 5) beside ours. Success at 0.03 m.\n",
        _markdown(table),
        "\n## Paired comparisons (a − b on identical environments)\n",
    ]
    if len(pairs):
        shown = pairs.copy()
        shown["mean_diff"] = shown.mean_diff.map(lambda v: f"{v:.3g}")
        shown["95% CI"] = [
            f"[{lo:.3g}, {hi:.3g}]" for lo, hi in zip(pairs.ci_low, pairs.ci_high, strict=False)
        ]
        shown["wilcoxon_p"] = shown.wilcoxon_p.map(lambda v: f"{v:.2g}")
        parts.append(
            _markdown(
                shown[["task", "a", "b", "metric", "pairs", "mean_diff", "95% CI", "wilcoxon_p"]]
            )
        )
    else:
        parts.append("(no pair of methods ran on the same environments)")
    parts.append("\n## The paper's claims in our numbers\n")
    parts.append(_markdown(pd.DataFrame(verdicts, columns=["claim", "verdict", "evidence"])))
    return "\n".join(parts) + "\n"


def write_outputs(root: Path, out_dir: Path) -> list[Path]:
    """Build every output in a temporary directory, then move them into ``out_dir``."""
    df = load_runs(root)
    ours = aggregate(df)
    table = combined(ours, paper_table())
    pairs = paired(df)
    verdicts = claims(ours)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = {
        "fig5.md": render_markdown(table, pairs, verdicts, root),
        "fig5.tex": table.to_latex(index=False, escape=True),
        "fig5.csv": ours.to_csv(index=False),
        "paired.csv": pairs.to_csv(index=False),
    }
    written = []
    with tempfile.TemporaryDirectory(dir=out_dir) as tmp:
        for name, text in names.items():
            (Path(tmp) / name).write_text(text)
        for name in names:
            os.replace(Path(tmp) / name, out_dir / name)
            written.append(out_dir / name)
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m analysis.table [RUNS] [--out DIR]``."""
    parser = OneLineParser(prog="make table", description="Fig. 5 from episodes.csv files")
    parser.add_argument("runs", nargs="?", default="runs", type=Path)
    parser.add_argument("--out", default=HERE / "out", type=Path)
    args = parser.parse_args(argv)
    try:
        written = write_outputs(args.runs, args.out)
    except (TableError, StoreError) as e:
        print(f"make table: error: {e}", file=sys.stderr)
        return 2
    print(Path(written[0]).read_text())
    for path in written:
        print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
