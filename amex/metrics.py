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
* ``compute_time_median`` / ``compute_time_mean``: wall time of the method's own outer step
  (``Method.step``), median and mean over the episode [s].
* ``failure``: empty, or why the episode ended early (``nan``, ``diverged``, ``solver: ...``).

Aggregates over a run are mean and 2 x standard deviation (population std, as Fig. 5's
"mean and two times the standard deviation").
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

    def as_row(self) -> dict[str, Any]:
        """The row as a dict in column order."""
        return asdict(self)


COLUMNS: tuple[str, ...] = tuple(f.name for f in fields(EpisodeResult))
#: Columns whose values depend on the machine's speed, not on the simulation.
TIMING_COLUMNS = ("compute_time_median", "compute_time_mean")
#: The metrics aggregated as mean and 2 std (Fig. 5's columns plus ours).
AGGREGATED = (
    "success",
    "success_005",
    "collided",
    "final_distance",
    "final_time",
    "sum_sq_acc",
    "compute_time_median",
    "compute_time_mean",
)


def mean_2std(values: Sequence[float]) -> dict[str, float]:
    """``{"mean": m, "two_std": 2 s}`` of ``values`` (population std); NaN for no values."""
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return {"mean": math.nan, "two_std": math.nan}
    return {"mean": float(a.mean()), "two_std": float(2.0 * a.std())}


def summarize(results: Sequence[EpisodeResult]) -> dict[str, Any]:
    """Aggregate a run: counts, failures, and mean / 2 std of every metric in :data:`AGGREGATED`."""
    rows = [r.as_row() for r in results]
    summary: dict[str, Any] = {
        "episodes": len(rows),
        "failures": sum(1 for r in rows if r["failure"]),
    }
    for key in AGGREGATED:
        summary[key] = mean_2std([float(r[key]) for r in rows])
    return summary
