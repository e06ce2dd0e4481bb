"""The pr2_like study's cells as its sweep ran them, by the part of the report they belong to.

The grids of ``conf/study/pr2_like.yaml`` name the parts: ``table*`` (every method on every task,
one grid per disturbance compensation of the inner controller), ``stall_*`` (Task-2 AMEX with
one change), ``fig6`` (logged episodes) and any other grid an AMEX variant on every task
(``kd400``). The stall analysis compares every Task-2 AMEX cell that is not logged, in the
study's declaration order, against the first (the table's, at the original gains).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .comparisons import paired_stats
from .sweep import Cell, StudyError, Sweep, read_sweep

STUDY = "pr2_like"
#: The stall table's rows of the table grids, by disturbance compensation.
COMPENSATION_LABELS = {
    "none": "pr2_like, original gains (Kp 1, Kd 100)",
    "observer": "disturbance observer in the inner loop",
    "integral": "integral action in the inner loop",
}
#: The stall table's other rows by grid (a grid not named here shows its overrides).
STALL_LABELS = {
    "stall_kp100": "Kp 100",
    "stall_kp400": "Kp 400",
    "stall_kp1000": "Kp 1000",
    "stall_kd200": "Kd 200",
    "kd400": "Kd 400",
    "stall_kp400_kd200": "Kp 400, Kd 200",
    "stall_dmp_gains": "Kp 400, Kd 40 (DMP's gains)",
    "stall_mass": "only mass x 1.2",
    "stall_friction": "only friction 0.3 N m",
    "stall_damping": "only damping 0.5 N m s",
    "stall_no_mismatch": "no mismatch (20 Hz, camera only)",
    "stall_exact_perception": "exact goal perception (mismatch only)",
    "stall_100hz": "100 Hz (mismatch, camera)",
}
#: Fig. 6's episodes by the inner controller's disturbance compensation.
FIG6_LABELS = {"none": "paper's controller", "observer": "disturbance observer"}
OFFSET_KD = (100.0, 200.0, 400.0)  # [1/s] velocity gains Kd of the steady velocity deficits


@dataclass(frozen=True)
class PR2Study:
    """The study's parts.

    Attributes:
        sweep: the sweep as it ran (:func:`analysis.sweep.read_sweep`).
        table: the table's episodes, with a ``compensation`` column (``controller.disturbance``).
        compensations: the compensations in the study's order (the paper's first).
        variants: each AMEX variant's episodes on every task, by grid name.
        stall: the stall analysis, one row per Task-2 AMEX cell (empty without stall grids).
        fig6: the logged cells, each with its label.
        reference: the cell the stall analysis compares with (Task 2, AMEX, the paper's gains).
    """

    sweep: Sweep
    table: pd.DataFrame
    compensations: tuple[str, ...]
    variants: dict[str, pd.DataFrame]
    stall: pd.DataFrame
    fig6: tuple[tuple[str, Cell], ...]
    reference: Cell

    @property
    def episodes(self) -> int:
        """Environments per cell of the table."""
        return int(self.reference.get("episodes"))

    @property
    def max_time(self) -> float:
        """The episodes' time limit [s]."""
        return float(self.reference.get("max_time"))


def _is_task2_amex(cell: Cell) -> bool:
    return cell.get("task") == 2 and cell.get("method.name") == "amex" and not cell.logged


def stall_rows(sweep: Sweep, cells: list[tuple[str, Cell]]) -> pd.DataFrame:
    """The stall table: each ``(grid, cell)`` against the first, one row each."""
    first = cells[0][1].episodes
    records = []
    for grid, cell in cells:
        g = cell.episodes
        extra = sweep.changed(cell)
        ft = paired_stats(g, first, ("final_time",)).iloc[0]
        max_time = float(cell.get("max_time"))
        label = STALL_LABELS.get(grid, " ".join(extra))
        if grid.startswith("table"):
            label = COMPENSATION_LABELS.get(str(cell.get("controller.disturbance")), label)
        records.append(
            {
                "variant": label,
                "overrides": " ".join(extra) or "(none)",
                "n": len(g),
                "success": g.success.mean(),
                "success_005": g.success_005.mean(),
                "timeouts": (g.final_time >= max_time - 1e-9).mean(),
                "final_time_mean": g.final_time.mean(),
                "final_distance_mean_cm": 100 * g.final_distance.mean(),
                "final_distance_max_cm": 100 * g.final_distance.max(),
                "sum_sq_acc_mean": g.sum_sq_acc.mean(),
                "final_time_diff_vs_original": ft.mean_diff,
                "diff_ci": f"[{ft.ci_low:.2f}, {ft.ci_high:.2f}]",
                "run_dir": str(cell.dirs[0]),
            }
        )
    return pd.DataFrame.from_records(records)


def read_study(runs: Path) -> PR2Study:
    """The study in ``runs`` by part (module notes).

    Raises:
        StudyError: no sweep of the study there, a cell without a complete run, or no table.
        TableError: an ``episodes.csv`` cannot be read, or shards overlap or leave gaps.
    """
    sweep = read_sweep(runs, STUDY)
    table: list[Cell] = []
    variants: dict[str, list[Cell]] = {}
    fig6: list[tuple[str, Cell]] = []
    stall: list[tuple[str, Cell]] = []
    for grid in sweep.grid_names:
        for cell in sweep.grid(grid):
            if cell.grids[0] != grid:  # declared by an earlier grid: counted there
                continue
            if cell.logged:
                disturbance = str(cell.get("controller.disturbance"))
                fig6.append((FIG6_LABELS.get(disturbance, disturbance), cell))
                continue
            if grid.startswith("table"):
                table.append(cell)
            elif not grid.startswith("stall_"):
                variants.setdefault(grid, []).append(cell)
            if _is_task2_amex(cell):
                stall.append((grid, cell))
    if not table:
        raise StudyError(f"{runs}: no table grid in the sweep (conf/study/{STUDY}.yaml)")
    reference = next((c for _, c in stall), None)
    if reference is None:
        raise StudyError(f"{runs}: no Task-2 AMEX cell to explain the stall with")
    frames = [c.episodes.assign(compensation=str(c.get("controller.disturbance"))) for c in table]
    compensations = tuple(dict.fromkeys(str(c.get("controller.disturbance")) for c in table))
    has_stall = any(g.startswith("stall_") for g in sweep.grid_names)
    return PR2Study(
        sweep=sweep,
        table=pd.concat(frames, ignore_index=True),
        compensations=compensations,
        variants={
            grid: pd.concat([c.episodes for c in cells], ignore_index=True)
            for grid, cells in variants.items()
        },
        stall=stall_rows(sweep, stall) if has_stall else pd.DataFrame(),
        fig6=tuple(fig6),
        reference=reference,
    )


@dataclass(frozen=True)
class Disturbance:
    """The unmodelled TCP acceleration at the reference's final pose, and what it costs AMEX.

    Attributes:
        gravity: ``(mass_scale - 1) |J M^-1 g|``: the task-space acceleration the inner PD must
            supply to hold the heavier arm still [m/s^2].
        friction: ``|J M^-1 f|`` with every joint's Coulomb friction ``f`` opposing at once
            (an upper bound) [m/s^2].
        offsets: the steady velocity error ``gravity / Kd`` for each Kd of :data:`OFFSET_KD`
            [m/s] (AMEX's PD carries a constant load with its velocity term alone).
    """

    gravity: float
    friction: float
    offsets: dict[float, float]


def disturbance(cell: Cell) -> Disturbance:
    """:class:`Disturbance` of the cell's robot and mismatch (rigid-body terms from Pinocchio)."""
    import pinocchio as pin

    from .model import reference_of, robot_of

    robot = robot_of(cell.config)
    model = robot.model
    data = model.createData()
    q = reference_of(cell.config, robot).q[-1]
    g = pin.computeGeneralizedGravity(model, data, q)
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T
    J = pin.computeFrameJacobian(model, data, q, robot.tcp_frame_id, pin.LOCAL_WORLD_ALIGNED)[:3]
    mass_scale = float(cell.get("mismatch.mass_scale"))
    gravity = float(np.linalg.norm(J @ np.linalg.solve(M, g))) * (mass_scale - 1)
    f = np.full(model.nv, float(cell.get("mismatch.friction")))
    friction = float(np.linalg.norm(J @ np.linalg.solve(M, f)))
    return Disturbance(gravity, friction, {kd: gravity / kd for kd in OFFSET_KD})
