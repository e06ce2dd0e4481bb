"""Beyond the paper: success and final time versus goal speed and goal perception, with prediction.

Task 2 (moving goal) on the nominal robot (100 Hz, no model mismatch), each method (AMEX, DMP, CR)
with and without the constant-velocity Kalman prediction of the perceived goal
(:mod:`amex.sim.perception`), in two sweeps:

* ``speed``: ``scenario.goal_speed_std`` x {0.5, 1, 2, 3}, the goal seen by a camera with 5 mm
  noise and 50 ms latency (the ``pr2_like`` perception);
* ``noise``: ``perception.noise_std`` in {0, 2, 5, 10} mm, latency 50 ms, goal speed x 1.

The cell (x 1, 5 mm) is in both sweeps and runs once. Goal velocities are drawn as
``std * N(0, 1)`` from the environment's seed, so environment *i* has the same goal direction in
every cell and the same goal in every method: all comparisons are paired. Then:

* ``paired``: the issue's criterion, AMEX with minus without prediction on the fast-goal cell
  (x 2): mean difference of final time, success and smoothness, bootstrap 95 % interval
  (:func:`analysis.table.bootstrap_ci`) and Wilcoxon signed-rank p; DMP and CR alongside;
* ``tuning``: AMEX with prediction on the same cell for a few ``lead_time`` / ``accel_std``
  values, each paired against AMEX without prediction.

The cells are the runs of a sweep, ``amex-run -m study=robustness`` (``conf/study/robustness.yaml``:
48 runs of 50 environments into ``runs/robustness/``, on any launcher, resumable, shardable);
this module runs no episode: it reads them (:mod:`analysis.study`: a cell's rows are those of its
configuration hash), refuses a missing or incomplete cell in one line, and checks the goals that
every method missed for reachability with IK (:func:`reach_errors`). A cell's configuration equals
``amex-run study=robustness method=M scenario.goal_speed_std=.. perception.noise_std=..
prediction.enabled=..`` plus the sweep's own command-line overrides. Outputs in
``analysis/out/``: ``robustness.md`` (tables), ``robustness.csv`` (one row per cell),
``robustness_speed.png`` and ``robustness_noise.png``.

Usage: ``python -m analysis.robustness [RUNS] [--quick] [--out DIR]`` (RUNS: runs/robustness).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from amex.app.argparsing import OneLineParser
from amex.core.palette import method_color, method_label
from analysis.table import _markdown, bootstrap_ci, load_runs

HERE = Path(__file__).resolve().parent
TASK = 2
LATENCY = 0.05  # [s]
SPEED_NOISE = 0.005  # [m] perception noise of the speed sweep
SPEED_FACTORS = (0.5, 1.0, 2.0, 3.0)
NOISE_LEVELS = (0.0, 0.002, 0.005, 0.010)  # [m]
STUDY_METHODS = ("amex", "dmp", "cr")
FAST = 2.0  # goal speed factor of the paired comparison
#: AMEX prediction variants tried on the fast-goal cell: (lead_time [s], accel_std [m/s^2]).
TUNING = ((0.0, 0.5), (0.0, 0.1), (0.0, 2.0), (0.1, 0.5), (0.2, 0.5), (0.2, 0.1), (0.4, 0.5))
PAIRED_METRICS = ("final_time", "success", "sum_sq_acc", "final_distance")


@dataclass(frozen=True)
class Cell:
    """One run of the study: a method under one goal speed and one perception, +- prediction.

    Attributes:
        method: method name.
        speed_factor: factor on the default ``scenario.goal_speed_std`` [-].
        noise_std: goal measurement noise per coordinate [m].
        prediction: Kalman prediction of the perceived goal on or off.
        lead_time: prediction lead beyond the present [s] (only with prediction).
        accel_std: the filter's white-acceleration noise [m/s^2] (only with prediction).
    """

    method: str
    speed_factor: float
    noise_std: float
    prediction: bool
    lead_time: float = 0.0
    accel_std: float = 0.5

    @property
    def name(self) -> str:
        """Directory name under the study's runs directory."""
        pred = "raw"
        if self.prediction:
            pred = "pred"
            if (self.lead_time, self.accel_std) != (0.0, 0.5):
                pred += f"_lead{self.lead_time:g}_acc{self.accel_std:g}"
        return (
            f"task{TASK}_speed{self.speed_factor:g}x_noise{self.noise_std * 1e3:g}mm"
            f"_lat{LATENCY * 1e3:g}ms_{self.method}_{pred}"
        )


@dataclass(frozen=True)
class Study:
    """The report's cells. The defaults are the full study; :func:`quick_study` a smoke version.

    Attributes:
        episodes: environments per cell (the sweep's, once read).
        speed_factors: goal speed factors of the speed sweep.
        noise_levels: perception noise levels of the noise sweep [m].
        methods: methods of both sweeps.
        tuning: AMEX prediction variants (lead_time, accel_std) on the fast-goal cell.
        overrides: config overrides of every cell beyond those its sweep recorded.
    """

    episodes: int = 50
    speed_factors: tuple[float, ...] = SPEED_FACTORS
    noise_levels: tuple[float, ...] = NOISE_LEVELS
    methods: tuple[str, ...] = STUDY_METHODS
    tuning: tuple[tuple[float, float], ...] = TUNING
    overrides: tuple[str, ...] = field(default_factory=tuple)

    def sweeps(self) -> list[tuple[str, Cell]]:
        """Every (sweep, cell) pair; a cell may appear in several sweeps."""
        out = []
        for m in self.methods:
            for pred in (False, True):
                out += [("speed", Cell(m, f, SPEED_NOISE, pred)) for f in self.speed_factors]
                out += [("noise", Cell(m, 1.0, n, pred)) for n in self.noise_levels]
        if "amex" in self.methods:
            out += [("tuning", Cell("amex", FAST, SPEED_NOISE, False))]
            out += [
                ("tuning", Cell("amex", FAST, SPEED_NOISE, True, lt, a)) for lt, a in self.tuning
            ]
        return out


def quick_study(overrides: Sequence[str] = ()) -> Study:
    """A smoke version: 2 environments, two speeds, two noise levels, one tuning variant."""
    return Study(
        episodes=2,
        speed_factors=(1.0, FAST),
        noise_levels=(0.0, SPEED_NOISE),
        tuning=((0.2, 0.5),),
        overrides=tuple(overrides),
    )


#: The keys the cells set (the sweep's own values of them are not shared by every cell).
CELL_KEYS = (
    "method",
    "scenario.goal_speed_std",
    "perception.noise_std",
    "prediction.enabled",
    "prediction.lead_time",
    "prediction.accel_std",
)
BASE_SPEED = 0.1  # [m/s] the configured scenario.goal_speed_std (conf/config.yaml)


def cell_overrides(cell: Cell) -> list[str]:
    """The overrides that make ``cell`` of the study (as ``conf/study/robustness.yaml`` does)."""
    speed = round(BASE_SPEED * cell.speed_factor, 12)
    out = [
        f"method={cell.method}",
        f"scenario.goal_speed_std={speed!r}",
        f"perception.noise_std={cell.noise_std!r}",
        f"prediction.enabled={'true' if cell.prediction else 'false'}",
    ]
    if cell.prediction and (cell.lead_time, cell.accel_std) != (0.0, 0.5):
        out += [
            f"prediction.lead_time={cell.lead_time!r}",
            f"prediction.accel_std={cell.accel_std!r}",
        ]
    return out


def cell_config(cell: Cell, overrides: Sequence[str] = ("study=robustness",)):
    """The validated :class:`~amex.experiment.config.RunConfig` of a cell (composed like its
    run)."""
    from analysis.study import cell_config as compose

    return compose(overrides, cell_overrides(cell))


def load_cells(study: Study, runs_dir: Path) -> tuple[Study, pd.DataFrame]:
    """Every cell's episodes from the sweep in ``runs_dir``, one row per (cell, env).

    ``study.overrides`` are added to those the sweep recorded (``multirun.yaml``). Returns the
    study with the sweep's ``episodes`` and all these overrides, and the episodes.

    Raises:
        StudyError: a cell has no runs or is incomplete.
        TableError: the runs cannot be read, or shards overlap or leave gaps.
    """
    from analysis.study import StudyError, cell_rows, sweep_overrides

    if not runs_dir.is_dir():
        raise StudyError(f"{runs_dir}: no such directory; run `amex-run -m study=robustness`")
    base = (*sweep_overrides(runs_dir, "robustness", CELL_KEYS), *study.overrides)
    episodes = load_runs(runs_dir)
    frames = []
    count = study.episodes
    for cell in dict.fromkeys(cell for _, cell in study.sweeps()):
        config = cell_config(cell, base)
        count = config.episodes
        df = cell_rows(episodes, config, cell.name, runs_dir)
        for key, value in dataclasses.asdict(cell).items():
            df[key] = value
        df["cell"] = cell.name
        df["goal_speed_std"] = config.scenario.goal_speed_std
        frames.append(df)
    study = dataclasses.replace(study, episodes=count, overrides=tuple(base))
    return study, pd.concat(frames, ignore_index=True)


def _ci(values: np.ndarray) -> tuple[float, float]:
    return bootstrap_ci(values.astype(float)) if len(values) else (math.nan, math.nan)


def aggregate(study: Study, episodes: pd.DataFrame) -> pd.DataFrame:
    """One row per (sweep, cell): success and final time with 95 % bootstrap intervals."""
    records = []
    for sweep, cell in study.sweeps():
        g = episodes[episodes.cell == cell.name]
        s_lo, s_hi = _ci(g.success.to_numpy())
        t_lo, t_hi = _ci(g.final_time.to_numpy())
        records.append(
            {
                "sweep": sweep,
                **dataclasses.asdict(cell),
                "goal_speed_std": g.goal_speed_std.iloc[0] if len(g) else math.nan,
                "latency": LATENCY,
                "episodes": len(g),
                "success": g.success.mean(),
                "success_ci_low": s_lo,
                "success_ci_high": s_hi,
                "success_005": g.success_005.mean(),
                "final_time_mean": g.final_time.mean(),
                "final_time_2std": 2.0 * g.final_time.std(ddof=0),
                "final_time_ci_low": t_lo,
                "final_time_ci_high": t_hi,
                "final_distance_mean": g.final_distance.mean(),
                "sum_sq_acc_mean": g.sum_sq_acc.mean(),
                "sum_sq_acc_2std": 2.0 * g.sum_sq_acc.std(ddof=0),
                "failures": int((g.failure != "").sum()),
                "cell": cell.name,
            }
        )
    return pd.DataFrame.from_records(records)


def paired_stats(
    a: pd.DataFrame, b: pd.DataFrame, metrics: Sequence[str] = PAIRED_METRICS
) -> pd.DataFrame:
    """Episodes ``a`` minus episodes ``b`` on the environments both ran, one row per metric.

    Each row: pairs, the two means, the mean difference, its bootstrap 95 % interval
    (:func:`analysis.table.bootstrap_ci`) and the Wilcoxon signed-rank p (NaN below 2 pairs).
    """
    from scipy.stats import wilcoxon

    wide_a, wide_b = a.set_index("env"), b.set_index("env")
    envs = wide_a.index.intersection(wide_b.index).sort_values()
    records = []
    for metric in metrics:
        va = wide_a.loc[envs, metric].astype(float).to_numpy()
        vb = wide_b.loc[envs, metric].astype(float).to_numpy()
        d = va - vb
        lo, hi = _ci(d)
        p = math.nan
        if len(d) >= 2:
            p = 1.0 if np.all(d == 0) else float(wilcoxon(d, zero_method="zsplit").pvalue)
        records.append(
            {
                "metric": metric,
                "pairs": len(d),
                "mean_a": float(va.mean()) if len(d) else math.nan,
                "mean_b": float(vb.mean()) if len(d) else math.nan,
                "mean_diff": float(d.mean()) if len(d) else math.nan,
                "ci_low": lo,
                "ci_high": hi,
                "wilcoxon_p": p,
            }
        )
    return pd.DataFrame.from_records(records)


def paired_difference(episodes: pd.DataFrame, a: Cell, b: Cell) -> pd.DataFrame:
    """Cell ``a`` minus cell ``b`` (see :func:`paired_stats`)."""
    stats = paired_stats(episodes[episodes.cell == a.name], episodes[episodes.cell == b.name])
    return stats.assign(a=a.name, b=b.name)


def comparisons(study: Study, episodes: pd.DataFrame) -> pd.DataFrame:
    """The paired comparisons of the report: prediction on minus off on the fast-goal cell."""
    frames = []
    if FAST in study.speed_factors:
        for m in study.methods:
            on, off = Cell(m, FAST, SPEED_NOISE, True), Cell(m, FAST, SPEED_NOISE, False)
            frames.append(paired_difference(episodes, on, off).assign(method=m, kind="prediction"))
    if "amex" in study.methods:
        off = Cell("amex", FAST, SPEED_NOISE, False)
        for lead, acc in study.tuning:
            on = Cell("amex", FAST, SPEED_NOISE, True, lead, acc)
            d = paired_difference(episodes, on, off)
            frames.append(d.assign(method="amex", kind=f"tuning lead {lead:g} s, accel {acc:g}"))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _fmt_rate(row: pd.Series) -> str:
    return f"{row.success:.2f} [{row.success_ci_low:.2f}, {row.success_ci_high:.2f}]"


def _fmt_time(row: pd.Series) -> str:
    return f"{row.final_time_mean:.2f} [{row.final_time_ci_low:.2f}, {row.final_time_ci_high:.2f}]"


def sweep_table(cells: pd.DataFrame, sweep: str) -> pd.DataFrame:
    """Display table of one sweep: per condition and method, without vs with prediction."""
    key, label = ("speed_factor", "goal speed") if sweep == "speed" else ("noise_std", "noise")
    sub = cells[cells.sweep == sweep]
    rows = []
    for (x, method), g in sub.groupby([key, "method"], sort=False):
        raw, pred = g[~g.prediction].iloc[0], g[g.prediction].iloc[0]
        cond = f"x {x:g} ({raw.goal_speed_std:.3g} m/s)" if sweep == "speed" else f"{x * 1e3:g} mm"
        rows.append(
            {
                label: cond,
                "method": method,
                "n": int(raw.episodes),
                "success": _fmt_rate(raw),
                "success, pred.": _fmt_rate(pred),
                "final time [s]": _fmt_time(raw),
                "final time, pred. [s]": _fmt_time(pred),
                "sum sq. acc.": f"{raw.sum_sq_acc_mean:.3g}",
                "sum sq. acc., pred.": f"{pred.sum_sq_acc_mean:.3g}",
            }
        )
    return pd.DataFrame.from_records(rows)


def comparison_table(pairs: pd.DataFrame) -> pd.DataFrame:
    """Display table of the paired comparisons."""
    shown = pd.DataFrame(
        {
            "method": pairs.method,
            "comparison": pairs.kind,
            "metric": pairs.metric,
            "pairs": pairs.pairs,
            "without": pairs.mean_b.map(lambda v: f"{v:.3g}"),
            "with": pairs.mean_a.map(lambda v: f"{v:.3g}"),
            "mean diff (with - without)": pairs.mean_diff.map(lambda v: f"{v:.3g}"),
            "95% CI": [
                f"[{lo:.3g}, {hi:.3g}]" for lo, hi in zip(pairs.ci_low, pairs.ci_high, strict=True)
            ],
            "wilcoxon_p": pairs.wilcoxon_p.map(lambda v: f"{v:.2g}"),
        }
    )
    return shown


def verdict(pairs: pd.DataFrame) -> str:
    """One sentence: does the default prediction help AMEX on fast goals (final time, success)?"""
    sel = pairs[(pairs.method == "amex") & (pairs.kind == "prediction")]
    if sel.empty:
        return "AMEX with and without prediction on fast goals: not run."
    ft = sel[sel.metric == "final_time"].iloc[0]
    su = sel[sel.metric == "success"].iloc[0]
    faster = ft.ci_high < 0 and ft.wilcoxon_p < 0.05
    slower = ft.ci_low > 0 and ft.wilcoxon_p < 0.05
    more = su.ci_low > 0
    fewer = su.ci_high < 0
    word = "faster" if faster else "slower" if slower else "not significantly different in time"
    succ = "more" if more else "fewer" if fewer else "no significant change in"
    return (
        f"AMEX on fast goals (x {FAST:g}), prediction on minus off over {int(ft.pairs)} paired "
        f"environments: final time {ft.mean_diff:+.3f} s [95 % CI {ft.ci_low:+.3f}, "
        f"{ft.ci_high:+.3f}], Wilcoxon p = {ft.wilcoxon_p:.2g} ({word}); success "
        f"{su.mean_diff:+.3f} [{su.ci_low:+.3f}, {su.ci_high:+.3f}] ({succ} successes)."
    )


def reach_errors(
    cell: Cell, envs: Sequence[int], overrides: Sequence[str] = ("study=robustness",)
) -> list[float]:
    """Top-down IK position error [m] of each environment's final goal (0: reachable)."""
    from amex.experiment.runner import prepare
    from amex.robot.ik import solve_ik
    from amex.sim.scenario import make_scenario

    config = cell_config(cell, overrides)
    context = prepare(config)
    out = []
    for env in envs:
        scenario = make_scenario(
            config.scenario, TASK, config.seed, env, context.plan.y[0, :3], context.plan.duration
        )
        goal = scenario.goal_at(math.inf)
        out.append(solve_ik(context.robot, goal, scenario.goal_axis).position_error)
    return out


def failures(
    cells: pd.DataFrame,
    failed: dict[str, list[int]],
    overrides: Sequence[str] = ("study=robustness",),
) -> str:
    """Which environments fail in the speed sweep (without prediction), per factor and method.

    Environments that fail for every method are checked for reachability: the top-down IK
    position error of the goal's final position (:func:`amex.robot.ik.solve_ik`).
    """
    lines = ["Failed environments (speed sweep, without prediction):\n"]
    sub = cells[(cells.sweep == "speed") & ~cells.prediction]
    for factor, g in sub.groupby("speed_factor"):
        sets = {r.method: failed.get(r.cell, []) for r in g.itertuples()}
        if not any(sets.values()):
            continue
        shown = "; ".join(f"{m}: {v or 'none'}" for m, v in sets.items())
        common = sorted(set.intersection(*(set(v) for v in sets.values())))
        note = ""
        if common:
            cell = Cell(g.method.iloc[0], float(factor), SPEED_NOISE, False)
            errs = reach_errors(cell, common, overrides)
            reach = sum(e < 1e-3 for e in errs)
            note = (
                f". Failing for every method: {common}; damped least-squares IK (top-down, from "
                f"q0) reaches {reach} of these final goals (smallest residual "
                f"{100 * min(errs):.1f} cm)"
            )
        lines.append(f"* x {factor:g}: {shown}{note}")
    return "\n".join(lines) if len(lines) > 1 else "No failures in the speed sweep."


def render(
    study: Study,
    cells: pd.DataFrame,
    pairs: pd.DataFrame,
    quick: bool,
    episodes_by_cell: dict[str, list[int]] | None = None,
) -> str:
    """The report as Markdown; ``episodes_by_cell``: failed environments per cell name."""
    episodes_by_cell = episodes_by_cell or {}
    title = "# Beyond the paper: goal speed, goal perception and goal prediction"
    parts = [title + (" (QUICK smoke run, not results)" if quick else "") + "\n"]
    parts.append(
        f"Task {TASK} (moving goal), nominal robot (100 Hz, no model mismatch), {study.episodes} "
        f"environments per cell, paired across cells and methods. The goal is perceived with "
        f"{LATENCY * 1e3:g} ms latency; prediction = constant-velocity Kalman filter "
        "(`prediction.enabled=true`, defaults accel_std 0.5 m/s², lead_time 0 s: it compensates "
        "the latency only). Success at 0.03 m on the true goal; final time = stop time "
        "(within 6 mm of the goal, else max_time 10 s). Brackets: bootstrap 95 % interval of the "
        "mean. Regenerate: `python -m analysis.robustness`.\n"
    )
    parts.append(
        f"\n## Goal speed (`scenario.goal_speed_std` x factor), {SPEED_NOISE * 1e3:g} mm noise\n"
    )
    parts.append(_markdown(sweep_table(cells, "speed")))
    parts.append("\n" + failures(cells, episodes_by_cell, study.overrides) + "\n")
    parts.append("\n## Perception noise (`perception.noise_std`), goal speed x 1\n")
    parts.append(_markdown(sweep_table(cells, "noise")))
    parts.append(
        f"\n## Paired: prediction on minus off, fast goals (x {FAST:g}, "
        f"{SPEED_NOISE * 1e3:g} mm, {LATENCY * 1e3:g} ms)\n"
    )
    parts.append(verdict(pairs) + "\n")
    if len(pairs):
        parts.append(_markdown(comparison_table(pairs)))
    return "\n".join(parts) + "\n"


def plot_sweep(cells: pd.DataFrame, sweep: str, path: Path) -> Path:
    """Success and final time versus the swept variable; solid with, dashed without prediction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    key = "speed_factor" if sweep == "speed" else "noise_std"
    sub = cells[cells.sweep == sweep].sort_values(key)
    scale = 1.0 if sweep == "speed" else 1e3
    xlabel = "goal speed factor (x default std)" if sweep == "speed" else "goal noise std [mm]"
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    panels = (
        ("success", "success_ci_low", "success_ci_high"),
        ("final_time_mean", "final_time_ci_low", "final_time_ci_high"),
        ("sum_sq_acc_mean", None, None),
    )
    methods = list(dict.fromkeys(sub.method))
    xs = np.sort(sub[key].unique()) * scale
    width = 0.012 * (xs.max() - xs.min() if len(xs) > 1 else 1.0)
    for i, method in enumerate(methods):
        for pred in (False, True):
            g = sub[(sub.method == method) & (sub.prediction == pred)]
            x = g[key].to_numpy() * scale + (i - 1 + (0.5 if pred else -0.5) / 2) * width
            style = dict(
                color=method_color(method),
                linestyle="-" if pred else "--",
                marker="o" if pred else "s",
                markersize=4,
                capsize=2,
                label=f"{method_label(method)}, " + ("prediction" if pred else "raw"),
            )
            for ax, (mean, lo, hi) in zip(axes, panels, strict=True):
                m = g[mean].to_numpy()
                err = None
                if lo is not None:
                    err = np.clip(np.vstack([m - g[lo].to_numpy(), g[hi].to_numpy() - m]), 0, None)
                ax.errorbar(x, m, yerr=err, **style)
    low = float(np.nanmin(sub.success_ci_low)) if len(sub) else 0.0
    axes[0].set_ylim(max(0.0, min(low - 0.05, 0.8)), 1.02)
    axes[0].set_ylabel("success rate (0.03 m)")
    axes[1].set_ylabel("final time [s] (10 s = time limit)")
    axes[2].set_ylabel("sum of squared joint accelerations")
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xlabel(xlabel)
        ax.set_xticks(xs)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8, ncol=1, loc="best")
    what = "goal speed (5 mm noise)" if sweep == "speed" else "goal noise (speed x 1)"
    n = int(sub.episodes.min()) if len(sub) else 0
    fig.suptitle(
        f"Task {TASK}, latency 50 ms: success, final time and smoothness vs {what}; "
        f"n = {n} paired environments, bars: unpaired 95 % CI of the mean"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def write_outputs(study: Study, runs_dir: Path, out_dir: Path, quick: bool = False) -> list[Path]:
    """Read the study's runs and write the report, the CSV and the two plots."""
    study, episodes = load_cells(study, runs_dir)
    cells = aggregate(study, episodes)
    pairs = comparisons(study, episodes)
    out_dir.mkdir(parents=True, exist_ok=True)
    md = out_dir / "robustness.md"
    csv = out_dir / "robustness.csv"
    failed = {
        name: sorted(int(e) for e in g.env[~g.success]) for name, g in episodes.groupby("cell")
    }
    md.write_text(render(study, cells, pairs, quick, failed))
    tmp = csv.with_suffix(".csv.tmp")
    cells.to_csv(tmp, index=False)
    os.replace(tmp, csv)
    written = [md, csv]
    for sweep in ("speed", "noise"):
        written.append(plot_sweep(cells, sweep, out_dir / f"robustness_{sweep}.png"))
    return written


def main(argv: list[str] | None = None) -> int:
    """Command line (see the module docstring)."""
    from amex.core.errors import AmexError
    from analysis import print_written

    parser = OneLineParser(prog="python -m analysis.robustness", description=__doc__)
    parser.add_argument("runs", nargs="?", type=Path, default=Path("runs/robustness"))
    parser.add_argument("--quick", action="store_true", help="the smoke study's cells only")
    parser.add_argument("--out", type=Path, default=HERE / "out")
    args = parser.parse_args(argv)
    study = quick_study() if args.quick else Study()
    return print_written(
        "python -m analysis.robustness",
        lambda: write_outputs(study, args.runs, args.out, quick=args.quick),
        (AmexError,),
    )


if __name__ == "__main__":
    raise SystemExit(main())
