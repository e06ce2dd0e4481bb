"""The robustness study's Markdown report: the two sweeps' tables, failures, paired comparisons."""

from __future__ import annotations

import pandas as pd

from .markdown import markdown_table
from .model import reach_errors
from .robustness_study import Study


def _fmt_rate(row: pd.Series) -> str:
    return f"{row.success:.2f} [{row.success_ci_low:.2f}, {row.success_ci_high:.2f}]"


def _fmt_time(row: pd.Series) -> str:
    return f"{row.final_time_mean:.2f} [{row.final_time_ci_low:.2f}, {row.final_time_ci_high:.2f}]"


def part_noise(study: Study, part: str) -> float:
    """The perception noise of the cells of ``part`` (the speed sweep's one value) [m]."""
    return max((cell.noise_std for cell in study.cells(part)), default=float("nan"))


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
    return pd.DataFrame(
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


def verdict(study: Study, pairs: pd.DataFrame) -> str:
    """One sentence: does the default prediction help AMEX on fast goals (final time, success)?"""
    sel = pairs[(pairs.method == "amex") & (pairs.kind == "prediction")] if len(pairs) else pairs
    if study.fast is None or sel.empty:
        return "AMEX with and without prediction on fast goals: not run."
    ft = sel[sel.metric == "final_time"].iloc[0]
    su = sel[sel.metric == "success"].iloc[0]
    faster = ft.ci_high < 0 and ft.wilcoxon_p < 0.05
    slower = ft.ci_low > 0 and ft.wilcoxon_p < 0.05
    word = "faster" if faster else "slower" if slower else "not significantly different in time"
    succ = "more" if su.ci_low > 0 else "fewer" if su.ci_high < 0 else "no significant change in"
    return (
        f"AMEX on fast goals (x {study.fast.speed_factor:g}), prediction on minus off over "
        f"{int(ft.pairs)} paired environments: final time {ft.mean_diff:+.3f} s [95 % CI "
        f"{ft.ci_low:+.3f}, {ft.ci_high:+.3f}], Wilcoxon p = {ft.wilcoxon_p:.2g} ({word}); "
        f"success {su.mean_diff:+.3f} [{su.ci_low:+.3f}, {su.ci_high:+.3f}] ({succ} successes)."
    )


def failures(study: Study, cells: pd.DataFrame, failed: dict[str, list[int]]) -> str:
    """Which environments fail in the speed sweep (without prediction), per factor and method.

    Environments that fail for every method are checked for reachability: the top-down IK
    position error of the goal's final position (:func:`analysis.model.reach_errors`).
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
            errs = reach_errors(study.configs[g.cell.iloc[0]], common)
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
    failed: dict[str, list[int]] | None = None,
) -> str:
    """The report as Markdown; ``failed``: failed environments per cell name."""
    latency = study.latency * 1e3
    noise = part_noise(study, "speed") * 1e3
    title = "# Beyond the paper: goal speed, goal perception and goal prediction"
    parts = [title + (" (QUICK smoke run, not results)" if quick else "") + "\n"]
    parts.append(
        f"Task {study.task} (moving goal), nominal robot (100 Hz, no model mismatch), "
        f"{study.episodes} environments per cell, paired across cells and methods. The goal is "
        f"perceived with {latency:g} ms latency; prediction = constant-velocity Kalman filter "
        "(`prediction.enabled=true`, defaults accel_std 0.5 m/s², lead_time 0 s: it compensates "
        "the latency only). Success at 0.03 m on the true goal; final time = stop time "
        "(within 6 mm of the goal, else max_time 10 s). Brackets: bootstrap 95 % interval of the "
        "mean. Regenerate: `python -m analysis.robustness`.\n"
    )
    parts.append(f"\n## Goal speed (`scenario.goal_speed_std` x factor), {noise:g} mm noise\n")
    parts.append(markdown_table(sweep_table(cells, "speed")))
    parts.append("\n" + failures(study, cells, failed or {}) + "\n")
    parts.append("\n## Perception noise (`perception.noise_std`), goal speed x 1\n")
    parts.append(markdown_table(sweep_table(cells, "noise")))
    fast = study.fast.speed_factor if study.fast is not None else float("nan")
    parts.append(
        f"\n## Paired: prediction on minus off, fast goals (x {fast:g}, {noise:g} mm, "
        f"{latency:g} ms)\n"
    )
    parts.append(verdict(study, pairs) + "\n")
    if len(pairs):
        parts.append(markdown_table(comparison_table(pairs)))
    return "\n".join(parts) + "\n"
