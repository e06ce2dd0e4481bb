"""The robustness study's cells as its sweep ran them, aggregated and compared in pairs.

The sweep of ``amex-run -m study=robustness`` (``conf/study/robustness.yaml``) names the report's
parts by its grids: ``speed`` and ``noise`` (each method with and without goal prediction) and
``tuning_*`` (AMEX's prediction variants on one fast goal). Each cell's values are read from its
run's configuration (:mod:`analysis.sweep`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .comparisons import bootstrap_ci, paired_stats
from .sweep import StudyError, Sweep, read_sweep

STUDY = "robustness"
TUNING = "tuning"  # the grids named tuning_*: AMEX's prediction variants on the fast goal


@dataclass(frozen=True)
class Cell:
    """One run of the study: a method under one goal speed and one perception, +- prediction.

    Attributes:
        method: method name.
        speed_factor: factor on the study's ``scenario.goal_speed_std`` [-].
        noise_std: goal measurement noise per coordinate [m].
        prediction: Kalman prediction of the perceived goal on or off.
        lead_time: prediction lead beyond the present [s].
        accel_std: the filter's white-acceleration noise [m/s^2].
        name: the cell's name in the report and the CSV.
    """

    method: str
    speed_factor: float
    noise_std: float
    prediction: bool
    lead_time: float
    accel_std: float
    name: str


@dataclass(frozen=True)
class Study:
    """The study as its sweep ran it.

    Attributes:
        task: the task of every cell.
        latency: goal perception latency of every cell [s].
        episodes: environments per cell.
        methods: the methods, in the sweep's order.
        parts: ``(part, cell)`` in report order: ``speed`` and ``noise`` per method, without
            then with prediction, then ``tuning``; a cell may be in several parts.
        fast: the tuning's cell without prediction (the paired comparisons' goal), or None.
        tuning: AMEX's prediction variants on that goal, by lead time, the default first.
        defaults: the study's prediction ``(lead_time, accel_std)``.
        configs: each cell's configuration by name (its ``.hydra/config.yaml``).
    """

    task: int
    latency: float
    episodes: int
    methods: tuple[str, ...]
    parts: tuple[tuple[str, Cell], ...]
    fast: Cell | None
    tuning: tuple[Cell, ...]
    defaults: tuple[float, float]
    configs: dict[str, dict[str, Any]]

    def cells(self, part: str) -> list[Cell]:
        """The cells of one part of the report."""
        return [cell for p, cell in self.parts if p == part]

    def find(self, method: str, like: Cell, prediction: bool) -> Cell | None:
        """The cell of ``method`` on ``like``'s goal, with or without default prediction."""
        for _, cell in self.parts:
            same_goal = (cell.speed_factor, cell.noise_std) == (like.speed_factor, like.noise_std)
            default = not prediction or (cell.lead_time, cell.accel_std) == self.defaults
            if cell.method == method and same_goal and cell.prediction == prediction and default:
                return cell
        return None


def _cell(sweep: Sweep, cell: Any) -> Cell:
    """The report's view of one cell of the sweep (its values read from its configuration)."""
    base_speed = float(sweep.config["scenario"]["goal_speed_std"])
    defaults = (sweep.config["prediction"]["lead_time"], sweep.config["prediction"]["accel_std"])
    factor = round(float(cell.get("scenario.goal_speed_std")) / base_speed, 12)
    noise = float(cell.get("perception.noise_std"))
    prediction = bool(cell.get("prediction.enabled"))
    lead, accel = float(cell.get("prediction.lead_time")), float(cell.get("prediction.accel_std"))
    method = str(cell.get("method.name"))
    pred = "raw"
    if prediction:
        pred = "pred" + ("" if (lead, accel) == defaults else f"_lead{lead:g}_acc{accel:g}")
    latency = float(cell.get("perception.latency")) * 1e3
    name = (
        f"task{cell.get('task')}_speed{factor:g}x_noise{noise * 1e3:g}mm_lat{latency:g}ms"
        f"_{method}_{pred}"
    )
    return Cell(method, factor, noise, prediction, lead, accel, name)


def _same(sweep: Sweep, key: str) -> Any:
    """The value every cell of the sweep has at ``key``."""
    values = {cell.get(key) for cell in sweep.cells}
    if len(values) != 1:
        raise StudyError(f"{sweep.runs}: the cells differ in {key} ({sorted(values)})")
    return values.pop()


def _parts(sweep: Sweep, view: dict[int, Cell]) -> tuple[list[tuple[str, Cell]], list[Cell]]:
    """The ``speed`` and ``noise`` parts in report order, and the cells of the tuning grids."""
    names = [name.split("_")[0] for name in sweep.grid_names]
    ranked, tuned = [], []
    for k, (grid, part) in enumerate(zip(sweep.grid_names, names, strict=True)):
        for i, c in enumerate(sweep.grid(grid)):
            if part == TUNING:
                tuned.append(view[id(c)])
            else:
                ranked.append(((names.index(part), k, i), part, view[id(c)]))
    methods = list(dict.fromkeys(cell.method for _, _, cell in ranked))
    # per method, without then with prediction: each part's cells in its grid's order
    ranked.sort(key=lambda r: (methods.index(r[2].method), r[2].prediction, *r[0]))
    return [(part, cell) for _, part, cell in ranked], tuned


def read_study(runs: Path) -> tuple[Study, pd.DataFrame]:
    """The study in ``runs`` and every cell's episodes (one row per cell and environment).

    Raises:
        StudyError: no sweep of the study there, or a cell without a complete run.
        TableError: an ``episodes.csv`` cannot be read, or shards overlap or leave gaps.
    """
    sweep = read_sweep(runs, STUDY)
    view = {id(c): _cell(sweep, c) for c in sweep.cells}
    parts, tuned = _parts(sweep, view)
    fast, tuning = None, []
    if tuned:
        goals = {(c.method, c.speed_factor, c.noise_std) for c in tuned}
        if len(goals) > 1:
            raise StudyError(f"{runs}: the tuning grids differ in method or goal ({goals})")
        on_goal = [
            view[id(c)]
            for c in sweep.cells
            if (view[id(c)].method, view[id(c)].speed_factor, view[id(c)].noise_std) in goals
        ]
        fast = next((c for c in on_goal if not c.prediction), None)
        if fast is None:
            raise StudyError(f"{runs}: no cell without prediction on the tuning grids' goal")
        tuning = sorted((c for c in on_goal if c.prediction), key=lambda c: c.lead_time)
        parts += [(TUNING, cell) for cell in (fast, *tuning)]
    prediction = sweep.config["prediction"]
    study = Study(
        task=int(_same(sweep, "task")),
        latency=float(_same(sweep, "perception.latency")),
        episodes=int(_same(sweep, "episodes")),
        methods=tuple(dict.fromkeys(cell.method for _, cell in parts)),
        parts=tuple(parts),
        fast=fast,
        tuning=tuple(tuning),
        defaults=(float(prediction["lead_time"]), float(prediction["accel_std"])),
        configs={view[id(c)].name: c.config for c in sweep.cells},
    )
    frames = [
        c.episodes.assign(cell=view[id(c)].name, goal_speed_std=c.get("scenario.goal_speed_std"))
        for c in sweep.cells
    ]
    return study, pd.concat(frames, ignore_index=True)


def _ci(values: np.ndarray) -> tuple[float, float]:
    return bootstrap_ci(values.astype(float)) if len(values) else (math.nan, math.nan)


def aggregate(study: Study, episodes: pd.DataFrame) -> pd.DataFrame:
    """One row per (part, cell): success and final time with 95 % bootstrap intervals."""
    records = []
    for part, cell in study.parts:
        g = episodes[episodes.cell == cell.name]
        s_lo, s_hi = _ci(g.success.to_numpy())
        t_lo, t_hi = _ci(g.final_time.to_numpy())
        records.append(
            {
                "sweep": part,
                "method": cell.method,
                "speed_factor": cell.speed_factor,
                "noise_std": cell.noise_std,
                "prediction": cell.prediction,
                "lead_time": cell.lead_time,
                "accel_std": cell.accel_std,
                "goal_speed_std": g.goal_speed_std.iloc[0] if len(g) else math.nan,
                "latency": study.latency,
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


def paired_difference(episodes: pd.DataFrame, a: Cell, b: Cell) -> pd.DataFrame:
    """Cell ``a`` minus cell ``b`` (:func:`analysis.comparisons.paired_stats`)."""
    stats = paired_stats(episodes[episodes.cell == a.name], episodes[episodes.cell == b.name])
    return stats.assign(a=a.name, b=b.name)


def comparisons(study: Study, episodes: pd.DataFrame) -> pd.DataFrame:
    """The report's paired comparisons: prediction on minus off on the fast goal, per method,
    then each of AMEX's prediction variants against AMEX without prediction."""
    frames = []
    if study.fast is not None:
        for m in study.methods:
            on, off = study.find(m, study.fast, True), study.find(m, study.fast, False)
            if on is not None and off is not None:
                d = paired_difference(episodes, on, off)
                frames.append(d.assign(method=m, kind="prediction"))
        for on in study.tuning:
            d = paired_difference(episodes, on, study.fast)
            kind = f"tuning lead {on.lead_time:g} s, accel {on.accel_std:g}"
            frames.append(d.assign(method=on.method, kind=kind))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
