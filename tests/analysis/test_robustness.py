"""The beyond-the-paper studies (analysis/robustness.py, analysis/pr2.py) at smoke size."""

from __future__ import annotations

import os

import pandas as pd
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as amex-run: results do not depend on it

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
    config = robustness.cell_config(cell)
    base = robustness.cell_config(robustness.Cell("amex", 1.0, 0.0, False))
    assert config.task == 2 and config.episodes == 50  # conf/study/robustness.yaml
    assert config.scenario.goal_speed_std == pytest.approx(2 * base.scenario.goal_speed_std)
    assert config.perception.noise_std == 0.01 and config.perception.latency == 0.05
    assert config.prediction.enabled and config.prediction.lead_time == 0.2
    assert config.prediction.accel_std == 0.1
    assert not base.prediction.enabled
    assert config.outer_hz == 100.0 and config.mismatch.mass_scale == 1.0


def _study_jobs(name):
    """The runs of ``amex-run -m study=<name>`` (what its sweeper launches), as configurations."""
    from amex.app.checks import sweep_settings
    from amex.app.compose import load_config
    from amex.app.sweeps import sweep_jobs

    params, grids, shards, _ = sweep_settings([f"study={name}"], [])
    return [load_config([f"study={name}", *job]) for job in sweep_jobs(params, grids, [], shards)]


def test_the_robustness_sweep_runs_exactly_the_report_cells_each_once():
    from amex.experiment.store import config_hash

    runs = [config_hash(c) for c in _study_jobs("robustness")]
    cells = {cell for _, cell in robustness.Study().sweeps()}
    assert len(runs) == len(set(runs)) == len(cells)
    assert set(runs) == {config_hash(robustness.cell_config(cell)) for cell in cells}


def test_the_pr2_sweep_runs_every_cell_of_the_report_once_and_logs_fig6():
    from amex.experiment.store import config_hash

    configs = _study_jobs("pr2_like")
    runs = [config_hash(c) for c in configs if c.log == "none"]
    assert len(runs) == len(set(runs))  # no cell twice (stall variants equal to a table cell)
    study = pr2.PR2Study()
    base = ("study=pr2_like",)
    cells = [
        (f"task={t}", f"method={m}", *pr2.COMPENSATIONS[c])
        for c in study.compensations
        for t in study.tasks
        for m in study.methods
    ]
    cells += [(f"task={t}", "method=amex", *pr2.KD400) for t in study.tasks]
    cells += [("task=2", "method=amex", *extra) for extra in study.stall.values()]
    from analysis.study import cell_config

    assert set(runs) == {config_hash(cell_config(base, cell)) for cell in cells}
    logged = [c for c in configs if c.log == "full"]
    assert [(c.task, c.method.name, c.episodes) for c in logged] == [(2, "amex", 1)] * 2
    assert {c.controller.disturbance for c in logged} == {"none", "observer"}


def _amex_run(args, cwd):
    import subprocess
    import sys
    from pathlib import Path

    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    command = [str(Path(sys.executable).parent / "amex-run"), *args]
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=env, timeout=600)


def test_the_robustness_study_runs_as_a_sweep_and_the_analysis_only_reads_it(tmp_path):
    runs = tmp_path / "runs"
    args = [
        "-m",
        "study=robustness",
        "episodes=2",
        *SHORT,
        "hydra.sweeper.params.method=amex",  # a smaller study: AMEX, one tuning grid
        "~hydra.sweeper.grids.tuning_accel",
        "~hydra.sweeper.grids.tuning_both",
        f"hydra.sweep.dir={runs}",
    ]
    proc = _amex_run(args, tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "17 jobs in" in proc.stderr.strip().splitlines()[-1]
    study = robustness.Study(methods=("amex",), tuning=((0.0, 0.5), (0.1, 0.5), (0.4, 0.5)))
    written = robustness.write_outputs(study, runs, tmp_path / "out")
    assert {p.name for p in written} == {
        "robustness.md",
        "robustness.csv",
        "robustness_speed.png",
        "robustness_noise.png",
    }
    cells = pd.read_csv(tmp_path / "out" / "robustness.csv")
    for col in ("sweep", "method", "prediction", "speed_factor", "noise_std", "success_ci_low"):
        assert col in cells.columns
    assert set(cells.sweep) == {"speed", "noise", "tuning"} and (cells.episodes == 2).all()
    report = (tmp_path / "out" / "robustness.md").read_text()
    assert "prediction on minus off" in report and "Wilcoxon" in report
    # the analysis starts no run: a cell the sweep did not run is one line, exit code 2
    missing = robustness.main([str(runs), "--out", str(tmp_path / "out2")])
    assert missing == 2 and not (tmp_path / "out2").exists()
    # the same command resumes: nothing left to run
    again = _amex_run(args, tmp_path)
    assert again.returncode == 0 and "17 jobs in" in again.stderr.strip().splitlines()[-1]
    assert len(list(runs.glob("*/episodes.csv"))) == 17


def test_pr2_experiment_composes_like_the_experiment_file():
    config = pr2.pr2_config(3, "dmp", 1)
    assert config.outer_hz == 20.0
    assert config.perception.noise_std == 0.005 and config.perception.latency == 0.05
    assert config.mismatch.mass_scale == 1.2 and config.mismatch.friction == 0.3
    assert config.method.pos.kd == 40.0  # the experiment leaves the methods' gains alone


def test_the_pr2_study_runs_as_a_sweep_and_fig6_comes_from_its_logs(tmp_path):
    runs = tmp_path / "runs"
    stall = [f"~hydra.sweeper.grids.{g}" for g in pr2_stall_grids()]
    args = [
        "-m",
        "study=pr2_like",
        "episodes=1",
        *SHORT,
        "hydra.sweeper.grids.table.task=2",
        "hydra.sweeper.grids.kd400.task=2",
        *stall,
        f"hydra.sweep.dir={runs}",
    ]
    proc = _amex_run(args, tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "12 jobs in" in proc.stderr.strip().splitlines()[-1]
    study = pr2.PR2Study(tasks=(2,), stall={"original": (), "Kd 400": pr2.KD400})
    written = pr2.write_outputs(study, runs, tmp_path / "out")
    assert [p.name for p in written] == ["pr2_like.md", "fig6_pr2_like.png"]
    assert written[1].stat().st_size > 10_000
    assert len(list(runs.glob("*/logs/episode_000.mcap"))) == 2
    report = written[0].read_text()
    assert "| 2 | amex |" in report and "| 2 | cr |" in report and "| 2 | dmp |" in report
    assert "Why AMEX stalls" in report and "Kd 400" in report
    assert "| 2 | amex | observer |" in report and "| 2 | cr | integral |" in report
    assert "| 2 | dmp observer | dmp none | final_time |" in report


def pr2_stall_grids():
    from omegaconf import OmegaConf

    conf = OmegaConf.load(pr2.HERE.parent / "conf" / "study" / "pr2_like.yaml")
    return [name for name in conf.hydra.sweeper.grids if name.startswith("stall_")]
