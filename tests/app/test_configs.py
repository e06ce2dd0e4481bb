"""Every config group option composes and validates; every experiment runs a few steps (slow)."""

from __future__ import annotations

from pathlib import Path

import pytest

from amex.app.compose import CONF_DIR, load_config
from amex.experiment.runner import run

CONF = Path(CONF_DIR)
ROBOTS = sorted(p.stem for p in (CONF / "robot").glob("*.yaml") if p.stem != "urdf")
EXPERIMENTS = sorted(
    str(p.relative_to(CONF / "experiment").with_suffix(""))
    for p in (CONF / "experiment").rglob("*.yaml")
)
METHODS = sorted(p.stem for p in (CONF / "method").glob("*.yaml"))


def test_the_experiment_list_includes_the_original_and_its_ablation():
    assert {"original", "pr2_like", "ablation/1_harness", "ablation/4_dynamic"} <= set(EXPERIMENTS)


@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_composes(experiment):
    config = load_config([f"experiment={experiment}", "method=cr", "task=3"])
    assert config.method.name == "cr"


@pytest.mark.parametrize("method", METHODS)
def test_every_method_composes_with_the_original_experiment(method):
    config = load_config(["experiment=original", f"method={method}"])
    assert (config.method.name, config.method.dir.weight) == (method, 1.0)


@pytest.mark.parametrize("robot", ROBOTS)
def test_every_robot_composes(robot):
    config = load_config([f"robot={robot}", "sim=kinematic"])
    assert (config.robot.name, config.sim) == (robot, "kinematic")


@pytest.mark.slow
@pytest.mark.parametrize("experiment", EXPERIMENTS)
def test_every_experiment_runs_an_episode(experiment, tmp_path):
    config = load_config([f"experiment={experiment}", "task=3", "method=cr", "episodes=1"])
    config.max_time = 0.5
    summary = run(config, tmp_path)
    assert summary["episodes"] == 1
