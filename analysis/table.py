"""``make table``: the paper's Fig. 5 from our runs, the paper's numbers beside ours, paired stats.

Reads every ``episodes.csv`` under a directory (default ``runs/``), groups the episodes by
benchmark configuration (scene hash; runs that differ only in ``seed`` pool into one,
:mod:`analysis.pooling`) and writes per group ``fig5.md``, ``fig5.csv``, ``fig5.tex`` and
``paired.csv`` into ``analysis/out/`` (one group) or ``analysis/out/scene_<id>/`` (several,
listed in ``fig5.md``). ``fig5.md`` also holds the intervals, the seeds' spread, the paired
comparisons and the paper's claims as test verdicts (``docs/statistics.md``). What each output
holds: ``docs/analysis.md``.

Usage: ``python -m analysis.table [RUNS_DIR] [--out DIR]``.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from amex.app.argparsing import OneLineParser
from amex.experiment.store import StoreError

from . import default_out
from .comparisons import METHOD_ORDER, method_rank, paired
from .episodes import TableError, load_runs
from .latex import fig5_latex
from .markdown import markdown_table, paired_markdown
from .pooling import benchmark_ids, recorded_config
from .verdict_tables import verdict_sections

#: Also importable from here, where they lived first (scripts and tests use them).
__all__ = ["TableError", "aggregate", "benchmarks", "load_runs", "main", "paired", "write_outputs"]

HERE = Path(__file__).resolve().parent
PAPER_CSV = HERE / "paper_fig5.csv"


@dataclass(frozen=True)
class Benchmark:
    """The episodes of one benchmark configuration: one scene hash, or several seeds pooled.

    ``scene_hash`` names it: the scene hash, or ``seeds-<digest>`` for seeds pooled, whose
    scene hashes are ``scene_hashes``.
    """

    scene_hash: str
    episodes: pd.DataFrame
    files: tuple[str, ...]
    overrides: tuple[str, ...]  # command-line overrides shared by its runs (task, method aside)
    seeds: tuple[int, ...] = (0,)
    scene_hashes: tuple[str, ...] = ()


def _overrides(files: list[str], pooled: bool = False) -> tuple[str, ...]:
    """The Hydra overrides every run of ``files`` shares, but task, method, episodes and log.

    ``pooled``: the runs are seeds pooled, so ``seed=`` is left out too.
    """
    import yaml

    common: set[str] | None = None
    for file in files:
        path = Path(file).parent / ".hydra" / "overrides.yaml"
        try:
            items = {str(o) for o in yaml.safe_load(path.read_text()) or []}
        except (OSError, yaml.YAMLError):
            items = set()
        common = items if common is None else common & items
    skip = ("task=", "method=", "episodes=", "log=", "hydra.", "+hydra.") + ("seed=",) * pooled
    return tuple(sorted(o for o in common or () if not o.startswith(skip)))


def benchmarks(df: pd.DataFrame) -> list[Benchmark]:
    """``df`` split into benchmarks (:mod:`analysis.pooling`), largest first.

    Method variants (two configurations of one task and method) are labelled
    ``method#<config hash>``, the config hash of the variant's lowest seed.
    """
    df = df.copy()
    if "code_hash" not in df:
        df["code_hash"] = ""
    df["benchmark"] = benchmark_ids(df)
    groups = []
    for name, g in df.groupby("benchmark", sort=False):
        g = g.copy()
        several = g.groupby(["task", "method"])["variant"].transform("nunique") > 1
        first = g.sort_values("seed", kind="stable").groupby("variant").config_hash.first()
        g.loc[several, "method"] = g.method[several] + "#" + g.variant[several].map(first).str[:6]
        g = g.drop_duplicates(subset=["task", "method", "seed", "env"], keep="first")
        files = sorted(set(g.file))
        seeds = tuple(sorted(int(s) for s in g.seed.unique()))
        hashes = tuple(sorted(set(g.scene_hash)))
        episodes = g.drop(columns=["benchmark", "scene_key", "variant"]).reset_index(drop=True)
        overrides = _overrides(files, pooled=len(hashes) > 1)
        groups.append(Benchmark(str(name), episodes, tuple(files), overrides, seeds, hashes))
    return sorted(groups, key=lambda b: (-len(b.episodes), b.scene_hash))


def _mean_2std(values: pd.Series, ddof: int = 0) -> tuple[float, float]:
    a = values.to_numpy(dtype=float)
    return float(a.mean()), float(2.0 * a.std(ddof=ddof)) if a.size > ddof else math.nan


def std_ddof(g: pd.DataFrame) -> int:
    """The ``std_ddof`` the runs of ``g`` recorded (``.hydra/config.yaml``; 0 without one).

    Raises:
        TableError: the runs of one cell recorded different values.
    """
    files = sorted(set(g.file)) if "file" in g else []
    values = {int((recorded_config(f) or {}).get("std_ddof", 0)) for f in files} or {0}
    if len(values) > 1:
        raise TableError(
            f"the runs of one cell recorded different std_ddof ({sorted(values)}): "
            f"{', '.join(files)}; valid: runs of one convention"
        )
    return values.pop()


def _column(g: pd.DataFrame, name: str, how: str) -> float:
    """``how`` (median, max, mean) of column ``name`` over the episodes; NaN if none has it."""
    if name not in g:
        return math.nan
    values = pd.to_numeric(g[name], errors="coerce").dropna()
    return float(getattr(values, how)()) if len(values) else math.nan


#: The columns of the compute tail, shown only when some run records them (:func:`combined`).
TAIL_COLUMNS = (
    "compute CPU p95 [s]",
    "compute CPU max [s]",
    "deadline misses",
    "budget stops",
)


def aggregate(df: pd.DataFrame) -> pd.DataFrame:
    """Fig. 5 per (task, method): means and 2 std (:mod:`amex.sim.metrics`).

    The standard deviations divide by N - ``std_ddof``, the value the runs recorded: 0 ours, 1
    the authors' (``experiment=original``).
    """
    records = []
    for (task, method), g in df.groupby(["task", "method"]):
        ddof = std_ddof(g)
        ft, ft2 = _mean_2std(g.final_time, ddof)
        acc, acc2 = _mean_2std(g.sum_sq_acc, ddof)
        paper_acc, paper_acc2 = _mean_2std(g.sum_sq_acc_paper, ddof)
        ct, ct2 = _mean_2std(g.compute_time_mean, ddof)
        records.append(
            {
                "task": task,
                "method": method,
                "episodes": len(g),
                "seeds": int(g.seed.nunique()) if "seed" in g else 1,
                "std_ddof": ddof,
                "success": g.success.mean(),
                "success_005": g.success_005.mean(),
                "collided": g.collided.mean(),
                "failures": int((g.failure != "").sum()),
                "final_time_mean": ft,
                "final_time_2std": ft2,
                "sum_sq_acc_mean": acc,
                "sum_sq_acc_2std": acc2,
                "sum_sq_acc_paper_mean": paper_acc,
                "sum_sq_acc_paper_2std": paper_acc2,
                "int_sq_acc_mean": float(g.int_sq_acc.mean()),
                "sum_sq_acc_t3_median": float(g.sum_sq_acc_t3.median()),
                "compute_time_mean": ct,
                "compute_time_2std": ct2,
                "compute_time_median": float(g.compute_time_median.median()),
                "compute_cpu_median": float(g.compute_cpu_median.median())
                if "compute_cpu_median" in g
                else math.nan,
                # the tail of the steps' CPU times, in runs that record it (older runs: NaN)
                "compute_cpu_p95": _column(g, "compute_cpu_p95", "median"),
                "compute_cpu_max": _column(g, "compute_cpu_max", "max"),
                "deadline_misses": _column(g, "deadline_misses", "mean"),
                "budget_stops": _column(g, "budget_stops", "mean"),
            }
        )
    out = pd.DataFrame.from_records(records)
    rank = {m: i for i, m in enumerate(METHOD_ORDER)}
    out["_rank"] = out.method.map(lambda m: rank.get(m, len(rank)))
    return out.sort_values(["task", "_rank", "method"]).drop(columns="_rank").reset_index(drop=True)


def paper_table() -> pd.DataFrame:
    """The paper's Fig. 5 as data."""
    return pd.read_csv(PAPER_CSV, comment="#")


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
                "seeds": r.seeds,
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
                "sum sq. acc. as the paper computed it": _pm(
                    r.sum_sq_acc_paper_mean, r.sum_sq_acc_paper_2std, ".2e"
                ),
                "compute [s]": _pm(r.compute_time_mean, r.compute_time_2std, ".2e"),
                "compute (paper)": _pm(r.compute_time_mean_paper, r.compute_time_2std_paper, ".2e"),
                "compute median [s]": f"{r.compute_time_median:.2e}",
                "compute CPU median [s]": ""
                if math.isnan(r.compute_cpu_median)
                else f"{r.compute_cpu_median:.2e}",
                "sum sq. acc. x T^3 (median)": f"{r.sum_sq_acc_t3_median:.2e}",
                TAIL_COLUMNS[0]: _fmt(r.compute_cpu_p95, ".2e"),
                TAIL_COLUMNS[1]: _fmt(r.compute_cpu_max, ".2e"),
                TAIL_COLUMNS[2]: _fmt(r.deadline_misses, ".4f"),
                TAIL_COLUMNS[3]: _fmt(r.budget_stops, ".4f"),
            }
        )
    out = pd.DataFrame.from_records(rows)
    if len(out) and not (out[TAIL_COLUMNS[0]] != "").any():  # runs from before the tail
        out = out.drop(columns=list(TAIL_COLUMNS))
    return out


def _fmt(value: float, fmt: str) -> str:
    return "" if math.isnan(value) else f"{value:{fmt}}"


def render_markdown(
    table: pd.DataFrame,
    pairs: pd.DataFrame,
    sections: list[str],
    source: Path,
    bench: Benchmark | None = None,
) -> str:
    """The whole report of one benchmark configuration as Markdown.

    ``sections``: what follows the paired comparisons
    (:func:`analysis.verdict_tables.verdict_sections`).
    """
    title = f"# Fig. 5, reproduced (from `{source}`)\n"
    if bench is not None:
        title += f"\nBenchmark configuration {_describe(bench)}.\n"
    parts = [
        title,
        "Mean ± 2 std over the environments of each run; the paper's numbers (Englert & "
        "Toussaint 2014, Fig. 5) beside ours. Success at 0.03 m. `n`: environments, over "
        "`seeds` seeds pooled.\n",
        markdown_table(table),
        "\n## Paired comparisons (a − b on identical environments)\n",
    ]
    if len(pairs):
        parts.append(paired_markdown(pairs))
    else:
        parts.append("(no two methods ran the same environments of a task)")
    parts += sections
    return "\n".join(parts) + "\n"


def _describe(bench: Benchmark) -> str:
    """``scene hash 1a2b...: robot=ur5 seed=3 (2 runs, tasks 1, 3; methods amex, dmp)``."""
    df = bench.episodes
    settings = " ".join(bench.overrides) or "the defaults"
    if len(bench.scene_hashes) > 1:
        seeds = ", ".join(str(s) for s in bench.seeds)
        settings += f"; seeds {seeds} pooled (their {len(bench.scene_hashes)} scene hashes)"
    tasks = ", ".join(str(t) for t in sorted(df.task.unique()))
    methods = ", ".join(sorted(set(df.method), key=method_rank))
    return (
        f"`{bench.scene_hash}`: {settings} ({len(bench.files)} run"
        f"{'s' if len(bench.files) != 1 else ''}, {len(df)} episodes; "
        f"tasks {tasks}; methods {methods})"
    )


def report(bench: Benchmark, source: Path) -> dict[str, str]:
    """The files of one benchmark configuration's report, by name."""
    ours = aggregate(bench.episodes)
    paper = paper_table()
    pairs = paired(bench.episodes)
    return {
        "fig5.md": render_markdown(
            combined(ours, paper), pairs, verdict_sections(bench.episodes, paper), source, bench
        ),
        "fig5.tex": fig5_latex(ours, paper),
        "fig5.csv": ours.to_csv(index=False),
        "paired.csv": pairs.to_csv(index=False),
    }


def _index(groups: list[Benchmark], source: Path) -> str:
    lines = [
        f"# Fig. 5 from `{source}`: {len(groups)} benchmark configurations\n",
        "Runs of different benchmark configurations (scene hashes: robot, scene scale, "
        "plan, controller, ...) ran different environments, so each has its own table, in "
        "`scene_<id>/` beside this file (runs that differ only in `seed` are one, pooled); "
        "`make table RUNS=<dir>` on one sweep's directory makes just its table.\n",
    ]
    for bench in groups:
        lines.append(f"* `scene_{bench.scene_hash}/fig5.md`: {_describe(bench)}")
        top = Path(os.path.commonpath(bench.files)) if bench.files else source
        lines.append(f"  runs under `{top if top.name != 'episodes.csv' else top.parent}`")
    return "\n".join(lines) + "\n"


def write_outputs(root: Path, out_dir: Path) -> list[Path]:
    """Build every output in a temporary directory, then move them into ``out_dir``."""
    groups = benchmarks(load_runs(root))
    files: dict[str, str] = {}
    if len(groups) == 1:
        files.update(report(groups[0], root))
    else:
        files["fig5.md"] = _index(groups, root)
        for bench in groups:
            texts = report(bench, root)
            files.update({f"scene_{bench.scene_hash}/{k}": v for k, v in texts.items()})
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    with tempfile.TemporaryDirectory(dir=out_dir) as tmp:
        for name, text in files.items():
            (Path(tmp) / name).parent.mkdir(parents=True, exist_ok=True)
            (Path(tmp) / name).write_text(text)
        if len(groups) > 1:  # the single-configuration outputs of an earlier call would mislead
            for name in ("fig5.tex", "fig5.csv", "paired.csv"):
                (out_dir / name).unlink(missing_ok=True)
        for name in files:
            (out_dir / name).parent.mkdir(parents=True, exist_ok=True)
            os.replace(Path(tmp) / name, out_dir / name)
            written.append(out_dir / name)
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m analysis.table [RUNS] [--out DIR]``."""
    parser = OneLineParser(prog="make table", description="Fig. 5 from episodes.csv files")
    parser.add_argument("runs", nargs="?", default="runs", type=Path)
    parser.add_argument("--out", default=default_out(), type=Path)
    args = parser.parse_args(argv)
    try:
        written = write_outputs(args.runs, args.out)
    except (TableError, StoreError) as e:
        print(f"make table: error: {e}", file=sys.stderr)
        return 2
    print(Path(written[0]).read_text())
    for path in written[1:]:  # several configurations: each one's Fig. 5 table after the index
        if path.name == "fig5.md":
            print(f"## {path.parent.name}\n")
            print(path.read_text().split("\n## Paired")[0].split("\n\n", 1)[1])
    for path in written:
        print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
