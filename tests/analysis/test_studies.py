"""The beyond-the-paper studies (analysis/robustness.py, analysis/pr2.py) at smoke size: each a
real sweep of ``amex-run -m study=...``, whose report reads only what the sweep wrote."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as amex-run: results do not depend on it

from analysis import pr2, robustness  # noqa: E402
from analysis.pr2_study import read_study  # noqa: E402

SHORT = ("max_time=0.4",)
CONF = Path(__file__).resolve().parents[2] / "conf"


def _study_jobs(name):
    """The runs of ``amex-run -m study=<name>`` (what its sweeper launches), as configurations."""
    from amex.app.checks import sweep_settings
    from amex.app.compose import load_config
    from amex.app.sweeps import sweep_jobs

    params, grids, shards, _ = sweep_settings([f"study={name}"], [])
    return [load_config([f"study={name}", *job]) for job in sweep_jobs(params, grids, [], shards)]


def _amex_run(args, cwd):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    command = [str(Path(sys.executable).parent / "amex-run"), *args]
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=env, timeout=600)


@pytest.mark.slow
def test_the_robustness_sweep_runs_every_configuration_once():
    from amex.experiment.store import config_hash

    configs = _study_jobs("robustness")
    assert len({config_hash(c) for c in configs}) == len(configs) == 48
    assert {c.task for c in configs} == {2} and {c.perception.latency for c in configs} == {0.05}
    assert {c.outer_hz for c in configs} == {100.0} and {c.episodes for c in configs} == {50}


@pytest.mark.slow
def test_the_pr2_sweep_runs_every_cell_once_and_logs_fig6():
    from amex.experiment.store import config_hash

    configs = _study_jobs("pr2_like")
    runs = [config_hash(c) for c in configs if c.log == "none"]
    assert len(runs) == len(set(runs)) == 52  # the stall variants equal to a table cell run once
    logged = [c for c in configs if c.log == "full"]
    assert [(c.task, c.method.name, c.episodes) for c in logged] == [(2, "amex", 1)] * 2
    assert {c.controller.disturbance for c in logged} == {"none", "observer"}


@pytest.mark.slow
def test_the_robustness_study_runs_as_a_sweep_and_the_report_only_reads_it(tmp_path):
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
    written = robustness.write_outputs(runs, tmp_path / "out")
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
    assert cells.cell.nunique() == 17  # every run of the sweep, each once
    speed = cells[cells.sweep == "speed"]
    assert list(speed.speed_factor) == [0.5, 1.0, 2.0, 3.0] * 2  # without, then with prediction
    assert list(cells[cells.sweep == "noise"].noise_std) == [0.0, 0.002, 0.005, 0.01] * 2
    tuning = cells[cells.sweep == "tuning"]
    assert list(tuning.prediction) == [False, True, True, True, True]
    assert list(tuning.lead_time) == [0.0, 0.0, 0.1, 0.2, 0.4]  # the default first
    report = (tmp_path / "out" / "robustness.md").read_text()
    assert "prediction on minus off" in report and "Wilcoxon" in report
    # the same command resumes: nothing left to run
    again = _amex_run(args, tmp_path)
    assert again.returncode == 0 and "17 jobs in" in again.stderr.strip().splitlines()[-1]
    assert len(list(runs.glob("*/episodes.csv"))) == 17
    # the report starts no run: a cell without its run, or with too few episodes, is one line
    cell = next(runs.glob("*prediction.lead_time=0.4*"))
    rows = (cell / "episodes.csv").read_text().splitlines(keepends=True)
    (cell / "episodes.csv").write_text("".join(rows[:2]))
    assert robustness.main([str(runs), "--out", str(tmp_path / "out2")]) == 2
    shutil.rmtree(cell)
    assert robustness.main([str(runs), "--out", str(tmp_path / "out2")]) == 2
    assert not (tmp_path / "out2").exists()


def test_a_missing_sweep_is_one_line_and_exit_2(tmp_path, capsys):
    assert pr2.main([str(tmp_path / "nothing"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "amex-run -m study=pr2_like" in err[0]


def test_pr2_experiment_composes_like_the_experiment_file():
    from amex.app.compose import load_config

    config = load_config(["experiment=pr2_like", "task=3", "method=dmp"])
    assert config.outer_hz == 20.0
    assert config.perception.noise_std == 0.005 and config.perception.latency == 0.05
    assert config.mismatch.mass_scale == 1.2 and config.mismatch.friction == 0.3
    assert config.method.pos.kd == 40.0  # the experiment leaves the methods' gains alone


def _pr2_grids():
    conf = yaml.safe_load((CONF / "study" / "pr2_like.yaml").read_text())
    return list(conf["hydra"]["sweeper"]["grids"])


@pytest.mark.slow
def test_the_pr2_study_runs_as_a_sweep_and_fig6_comes_from_its_logs(tmp_path):
    runs = tmp_path / "runs"
    grids = _pr2_grids()
    stall = [f"~hydra.sweeper.grids.{g}" for g in grids if g.startswith("stall_")][1:]
    tables = [f"hydra.sweeper.grids.{g}.task=2" for g in grids if g.startswith("table")]
    args = [
        "-m",
        "study=pr2_like",
        "episodes=1",
        *SHORT,
        *tables,
        "hydra.sweeper.grids.kd400.task=2",
        *stall,  # all but the first stall grid (Kp 100)
        f"hydra.sweep.dir={runs}",
    ]
    proc = _amex_run(args, tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "13 jobs in" in proc.stderr.strip().splitlines()[-1]
    written = pr2.write_outputs(runs, tmp_path / "out")
    assert [p.name for p in written] == ["pr2_like.md", "fig6_pr2_like.png"]
    assert written[1].stat().st_size > 10_000
    assert len(list(runs.glob("*/logs/episode_000.mcap"))) == 2
    report = written[0].read_text()
    assert "| 2 | amex |" in report and "| 2 | cr |" in report and "| 2 | dmp |" in report
    assert "| 2 | amex | observer |" in report and "| 2 | cr | integral |" in report
    assert "| 2 | dmp observer | dmp none | final_time |" in report
    assert "## AMEX with `method.pos.kd=400 method.dir.kd=400` (deviation)" in report
    study = read_study(runs)
    assert list(study.stall.variant) == [
        "pr2_like, original gains (Kp 1, Kd 100)",
        "Kp 100",
        "Kd 400",
        "disturbance observer in the inner loop",
        "integral action in the inner loop",
    ]
    assert list(study.stall.overrides)[:3] == [
        "(none)",
        "method.pos.kp=100 method.dir.kp=100",
        "method.pos.kd=400 method.dir.kd=400",
    ]
    assert [label for label, _ in study.fig6] == ["paper's controller", "disturbance observer"]
