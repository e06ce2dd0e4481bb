"""The comparison's analysis (analysis/baselines.py): directory names, the tuning rule, verdicts."""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.baselines import (
    METHODS,
    cell_of,
    choose,
    paired_rows,
    paired_table,
    robot_of,
    summary,
)


def test_the_robot_and_the_cell_are_read_from_the_run_directory():
    assert robot_of("runs/baselines/method=cbf_ik,robot=ur5,task=3/episodes.csv") == "ur5"
    assert robot_of("docs/data/runs/paper/task3_amex_seed0/episodes.csv") == "panda"
    path = "runs/tuning_cbf_ik/method.barrier_gain=5.0,method.gain=2.0,method=cbf_ik,task=1/x.csv"
    assert cell_of(path) == "barrier_gain=5.0,gain=2.0"


def test_the_rule_prefers_success_then_smoothness_within_one_episode():
    cells = pd.DataFrame(
        {
            "cell": ["a", "b", "c"],
            "mean success": [1.0, 0.98, 0.9],  # b within 1/40 of a, c not
            "mean sum_sq_acc": [50.0, 10.0, 1.0],
        }
    )
    assert choose(cells) == "b"
    cells.loc[1, "mean success"] = 0.95
    assert choose(cells) == "a"


def _episodes(rng, method, success, final_time, n=40):
    return pd.DataFrame(
        {
            "task": 3,
            "method": method,
            "env": np.arange(n),
            "seed": 0,
            "success": success,
            "final_time": final_time,
            "sum_sq_acc": rng.uniform(1, 2, n),
            "plan_fidelity": rng.uniform(0, 1, n),
            "min_clearance": rng.uniform(0.01, 0.03, n),
            "deadline_misses": 0.0,
            "compute_cpu_median": 1e-4,
        }
    )


def test_a_clearly_faster_method_is_named_better_and_equal_success_is_not():
    rng = np.random.default_rng(0)
    t = rng.uniform(3, 4, 40)
    df = pd.concat(
        [
            _episodes(rng, "amex", np.ones(40, bool), t + 1.0),
            _episodes(rng, "cbf_ik", np.ones(40, bool), t),
        ],
        ignore_index=True,
    )
    table = paired_table(paired_rows(df, [("cbf_ik", "amex")])).set_index("metric")
    assert table.loc["final_time", "better"] == "cbf_ik"
    assert table.loc["success", "better"] == "-"
    rows = summary(df)
    assert list(rows.method) == [m for m in METHODS if m in {"amex", "cbf_ik"}]
    assert rows["success [95% CI]"].iloc[0].startswith("1.00 [0.91, 1.00]")
