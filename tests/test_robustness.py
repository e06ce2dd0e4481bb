"""The beyond-the-paper studies (analysis/robustness.py, analysis/pr2.py) at smoke size."""

from __future__ import annotations

import os

import pandas as pd
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

from analysis import pr2, robustness  # noqa: E402

SHORT = ("max_time=0.4",)


def test_study_cells_are_paired_and_named_uniquely():
    study = robustness.Study()
    cells = {cell for _, cell in study.sweeps()}
    names = {cell.name for cell in cells}
    assert len(names) == len(cells)
    # the (x 1, 5 mm) cell belongs to both sweeps but runs once
    shared = robustness.Cell("amex", 1.0, robustness.SPEED_NOISE, True)
    sweeps = {s for s, c in study.sweeps() if c == shared}
    assert sweeps == {"speed", "noise"}
    assert len(cells) == 2 * 3 * 7 + len(robustness.TUNING) - 1


def test_cell_config_sets_speed_noise_latency_and_prediction():
    cell = robustness.Cell("amex", 2.0, 0.01, True, lead_time=0.2, accel_std=0.1)
    config = robustness.cell_config(cell, 3)
    base = robustness.cell_config(robustness.Cell("amex", 1.0, 0.0, False), 3)
    assert config.task == 2 and config.episodes == 3
    assert config.scenario.goal_speed_std == pytest.approx(2 * base.scenario.goal_speed_std)
    assert config.perception.noise_std == 0.01 and config.perception.latency == 0.05
    assert config.prediction.enabled and config.prediction.lead_time == 0.2
    assert config.prediction.accel_std == 0.1
    assert not base.prediction.enabled
    assert config.outer_hz == 100.0 and config.mismatch.mass_scale == 1.0


def test_quick_robustness_study_writes_report_csv_and_plots(tmp_path):
    study = robustness.Study(
        episodes=2,
        speed_factors=(robustness.FAST,),
        noise_levels=(robustness.SPEED_NOISE,),
        methods=("amex", "dmp"),
        tuning=((0.2, 0.5),),
        overrides=SHORT,
    )
    written = robustness.write_outputs(study, tmp_path / "runs", tmp_path / "out", quick=True)
    names = {p.name for p in written}
    assert names == {
        "robustness.md",
        "robustness.csv",
        "robustness_speed.png",
        "robustness_noise.png",
    }
    for path in written:
        assert path.stat().st_size > 0
    cells = pd.read_csv(tmp_path / "out" / "robustness.csv")
    for col in (
        "sweep",
        "method",
        "prediction",
        "speed_factor",
        "noise_std",
        "episodes",
        "success",
        "success_ci_low",
        "final_time_mean",
        "final_time_ci_high",
    ):
        assert col in cells.columns
    assert set(cells.sweep) == {"speed", "noise", "tuning"}
    assert (cells.episodes == 2).all()
    report = (tmp_path / "out" / "robustness.md").read_text()
    assert "prediction on minus off" in report and "Wilcoxon" in report
    pairs = robustness.comparisons(study, robustness.run_cells(study, tmp_path / "runs"))
    assert {"final_time", "success"} <= set(pairs.metric)
    assert {"amex", "dmp"} == set(pairs.method)
    # resumable: a second call runs nothing new and gives the same table
    again = robustness.aggregate(study, robustness.run_cells(study, tmp_path / "runs"))
    assert again.success.tolist() == cells.success.tolist()


def test_pr2_experiment_composes_like_the_experiment_file():
    config = pr2.pr2_config(3, "dmp", 1)
    assert config.outer_hz == 20.0
    assert config.perception.noise_std == 0.005 and config.perception.latency == 0.05
    assert config.mismatch.mass_scale == 1.2 and config.mismatch.friction == 0.3
    assert config.method.pos.kd == 40.0  # the experiment leaves the methods' gains alone


def test_pr2_experiment_runs_every_method_and_draws_fig6(tmp_path):
    study = pr2.PR2Study(
        episodes=1,
        stall_episodes=1,
        tasks=(2,),
        stall={"original": (), "Kd 400": pr2.KD400},
        overrides=SHORT,
    )
    written = pr2.write_outputs(study, tmp_path / "runs", tmp_path / "out")
    assert [p.name for p in written] == ["pr2_like.md", "fig6_pr2_like.png"]
    assert written[1].stat().st_size > 10_000
    for method in pr2.PR2_METHODS:
        for name in ("pr2_like", "pr2_like_observer", "pr2_like_integral"):
            assert (tmp_path / "runs" / name / f"task2_{method}_seed0" / "episodes.csv").exists()
    report = written[0].read_text()
    assert "| 2 | amex |" in report and "| 2 | cr |" in report and "| 2 | dmp |" in report
    assert "Why AMEX stalls" in report and "Kd 400" in report
    assert "| 2 | amex | observer |" in report and "| 2 | cr | integral |" in report
    assert "| 2 | dmp observer | dmp none | final_time |" in report
