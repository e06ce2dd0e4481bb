"""Per-episode metrics and their aggregation, defined once (the README quotes these definitions).

* ``success``: the final TCP-goal distance is at most ``success_radius`` (0.03 m, the paper's
  threshold) and no failure occurred. The episode stops when the TCP is within ``stop_radius``
  (0.03 m x scale = 6 mm, the paper's precision relative to its larger scene) of the *current*
  goal, or at ``max_time``.
* ``success_005``: the final TCP-goal distance is at most 0.05 m (the authors' evaluation script
  counted success at < 0.05 m although the paper states 0.03 m).
* ``collided``: the arm touched an obstacle (a MuJoCo contact) at any time; reported apart.
* ``final_distance``: TCP-goal distance when the episode stopped [m].
* ``final_time``: when the episode stopped (goal reached, ``max_time`` or a failure) [s].
* ``sum_sq_acc``: sum over all simulation steps (1 kHz) and all joints of the squared joint
  acceleration, ``sum_k sum_j qdd_j(k)^2`` [rad^2/s^4], without a dt factor, as the original.
  It grows with the rate: doubling ``inner_hz`` doubles it.
* ``int_sq_acc``: the same as an integral, ``int ||qdd||^2 dt = sum_k ||qdd(k)||^2 dt``
  [rad^2/s^3]: independent of the simulation rate.
* ``sum_sq_acc_paper``: the figure of the paper's Fig. 5 as the authors computed it
  (``matlab/evalRun.m``): the joint angles of every inner step written with 6 significant digits
  (:func:`round_significant`), differentiated twice with MATLAB's ``gradient`` (central
  differences inside, one-sided at the ends; :func:`paper_sum_sq_acc`), squared and summed over
  samples and joints, no dt. The rounding noise of about 1e-6 rad in q becomes ~1 rad/s^2 in the
  second difference at 1 ms, so at |q| >= 1 rad it adds roughly 3 (rad/s^2)^2 per joint and
  sample: most of the paper's AMEX and CR values.
* ``compute_time_median`` / ``compute_time_mean``: wall time of the method's own outer step
  (``Method.step``), median and mean over the episode [s].
* ``compute_cpu_median`` / ``compute_cpu_mean``: the same on the thread's CPU time [s]: what a
  step costs, whatever else the machine does (compute claims are judged on it).
* ``deadline_misses``: the fraction of outer steps whose thread CPU time exceeded the outer
  period ``1 / outer_hz`` [-].
* ``compute_cpu_p95`` / ``compute_cpu_max``: the 95th percentile and the maximum of the outer
  steps' thread CPU times [s] (the tail a deadline sees).
* ``budget_stops``: the fraction of outer steps a method with a time budget cut short on it
  (its ``early_stops`` count over the steps, e.g. MPPI's; NaN for a method without a budget) [-].
* ``min_clearance``: the smallest arm-obstacle distance at the outer steps [m] (negative:
  penetration; NaN in a scene without obstacles).
* ``final_axis_error``: the angle between the TCP z-axis and the goal axis at the end [rad].
* ``path_length``: the length of the TCP path over every inner step [m].
* ``plan_fidelity``: how far the executed TCP path is from the reference plan's shape moved to
  the goal's final position [m]: with the reference TCP positions ``R_k`` (k = 0..N, ``R_N`` its
  goal) and the goal ``g_T`` where the episode ended, the moved shape is the polyline through
  ``R'_k = R_k + (k / N) (g_T - R_N)``, and the fidelity is the mean, over the TCP positions at
  the outer steps, of their distance to that polyline. Method-independent; 0 for a TCP that
  follows the reference exactly on Task 0 (there ``g_T = R_N``).
* ``failure``: empty, or why the episode ended early (``nan``, ``diverged``, ``solver: ...``).

Aggregates over a run are mean and 2 x standard deviation, by default the population's
(``ddof=0``, ours). The authors' Fig. 5 took MATLAB's ``std``, the sample standard deviation
(``ddof=1``, divided by N - 1; ``matlab/evalScenario.m``): at N = 150 it is 0.33 % larger.
``summarize(..., ddof=1)`` and ``mean_2std(..., ddof=1)`` give theirs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

SUCCESS_005_RADIUS = 0.05  # [m]


@dataclass(frozen=True)
class EpisodeResult:
    """One row of ``episodes.csv``."""

    task: int
    method: str
    env: int
    seed: int
    success: bool
    success_005: bool
    collided: bool
    final_distance: float
    final_time: float
    sum_sq_acc: float
    compute_time_median: float
    compute_time_mean: float
    failure: str
    sum_sq_acc_paper: float = math.nan
    int_sq_acc: float = math.nan
    compute_cpu_median: float = math.nan
    compute_cpu_mean: float = math.nan
    deadline_misses: float = math.nan
    min_clearance: float = math.nan
    final_axis_error: float = math.nan
    path_length: float = math.nan
    plan_fidelity: float = math.nan
    compute_cpu_p95: float = math.nan
    compute_cpu_max: float = math.nan
    budget_stops: float = math.nan

    def as_row(self) -> dict[str, Any]:
        """The row as a dict in column order."""
        return asdict(self)


COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(EpisodeResult))
#: The columns every episodes.csv has; later ones (added metrics) may be missing in old files.
REQUIRED_COLUMNS: tuple[str, ...] = COLUMNS[: COLUMNS.index("failure") + 1]
#: Columns whose values depend on the machine's speed, not on the simulation.
TIMING_COLUMNS = (
    "compute_time_median",
    "compute_time_mean",
    "compute_cpu_median",
    "compute_cpu_mean",
    "deadline_misses",
    "compute_cpu_p95",
    "compute_cpu_max",
    "budget_stops",
)
#: The metrics aggregated as mean and 2 std (Fig. 5's columns plus ours).
AGGREGATED = (
    "success",
    "success_005",
    "collided",
    "final_distance",
    "final_time",
    "sum_sq_acc",
    "sum_sq_acc_paper",
    "int_sq_acc",
    "compute_time_median",
    "compute_time_mean",
    "compute_cpu_median",
    "compute_cpu_mean",
    "deadline_misses",
    "compute_cpu_p95",
    "compute_cpu_max",
    "budget_stops",
    "min_clearance",
    "final_axis_error",
    "path_length",
    "plan_fidelity",
)


def mean_2std(values: Sequence[float], ddof: int = 0) -> dict[str, float]:
    """``{"mean": m, "two_std": 2 s}`` of ``values``; NaN for no values.

    Args:
        values: the episodes' values.
        ddof: the standard deviation's delta degrees of freedom: 0, the population's (ours), or
            1, the sample's (MATLAB's ``std``, the authors'; NaN for a single value).
    """
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return {"mean": math.nan, "two_std": math.nan}
    two_std = float(2.0 * a.std(ddof=ddof)) if a.size > ddof else math.nan
    return {"mean": float(a.mean()), "two_std": two_std}


def summarize(results: Sequence[EpisodeResult], ddof: int = 0) -> dict[str, Any]:
    """Aggregate a run: counts, failures, and mean / 2 std of every metric in :data:`AGGREGATED`.

    ``ddof``: as :func:`mean_2std` (0: ours; 1: the authors' MATLAB ``std``).
    """
    rows = [r.as_row() for r in results]
    summary: dict[str, Any] = {
        "episodes": len(rows),
        "failures": sum(1 for r in rows if r["failure"]),
    }
    for key in AGGREGATED:
        summary[key] = mean_2std([float(r[key]) for r in rows], ddof)
    return summary


def round_significant(x: np.ndarray, digits: int = 6) -> np.ndarray:
    """``x`` rounded to ``digits`` significant digits, as ``printf("%g")`` writes it.

    Vectorized (``round(x 10^k) / 10^k`` with ``k = digits - 1 - floor(log10 |x|)``); it can differ
    from the text in the last digit on exact ties. Zeros and non-finite values pass unchanged.
    """
    x = np.asarray(x, dtype=float)
    out = x.copy()
    ok = np.isfinite(x) & (x != 0.0)
    scale = 10.0 ** (digits - 1 - np.floor(np.log10(np.abs(x[ok]))))
    out[ok] = np.round(x[ok] * scale) / scale
    return out


def paper_sum_sq_acc(q: np.ndarray, dt: float, digits: int = 6) -> float:
    """The paper's "sum of squared accelerations" of joint samples ``q`` (T, n) at period ``dt``.

    See the module notes: 6 significant digits, MATLAB's ``gradient`` twice, no dt.
    """
    if len(q) < 2:
        return 0.0
    rounded = round_significant(q, digits)
    qdd = np.gradient(np.gradient(rounded, dt, axis=0), dt, axis=0)
    return float(np.sum(qdd * qdd))


def axis_error(axis: Any, goal_axis: Any) -> float:
    """The angle between two axes [rad] (NaN if either is not finite or zero)."""
    a, g = np.asarray(axis, dtype=float), np.asarray(goal_axis, dtype=float)
    norms = float(np.linalg.norm(a) * np.linalg.norm(g))
    if not (math.isfinite(norms) and norms > 0.0):
        return math.nan
    return float(math.acos(min(1.0, max(-1.0, float(a @ g) / norms))))


def plan_fidelity(tcp: np.ndarray, reference: np.ndarray, goal_end: np.ndarray) -> float:
    """``plan_fidelity`` (module notes): mean distance of ``tcp`` to the moved reference [m].

    Args:
        tcp: TCP positions at the outer steps, shape (J, 3) [m].
        reference: the reference plan's TCP positions, shape (N + 1, 3) [m].
        goal_end: the goal where the episode ended, shape (3,) [m].
    """
    R = np.asarray(reference, dtype=float)[:, :3]
    P = np.asarray(tcp, dtype=float)
    if len(R) < 2 or not len(P) or not np.isfinite(P).all():
        return math.nan
    u = np.linspace(0.0, 1.0, len(R))[:, None]
    moved = R + u * (np.asarray(goal_end, dtype=float)[:3] - R[-1])
    A, D = moved[:-1], np.diff(moved, axis=0)  # segments A + w D, w in [0, 1]
    dd = np.einsum("ij,ij->i", D, D)
    total = 0.0
    for chunk in np.array_split(P, max(1, len(P) // 256)):  # bounded memory
        rel = chunk[:, None, :] - A[None, :, :]
        w = np.clip(np.einsum("jik,ik->ji", rel, D) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
        gap = rel - w[..., None] * D[None, :, :]
        total += float(np.sqrt(np.einsum("jik,jik->ji", gap, gap).min(axis=1)).sum())
    return total / len(P)
