"""One construction for every method, ``Cls(plan, config, dt, robot)``, checked once in the base.

Parametrized over the registry and the authors' implementations, so a method added later is
held to the same convention. Real robot and planner (the ``robot`` fixture of ``conftest.py``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import types
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from amex.app.compose import load_config
from amex.core.errors import ConfigError
from amex.core.schema import check_tree
from amex.experiment.config import RunConfig
from amex.experiment.runner import preflight
from amex.methods import (
    AMEX,
    BUILTIN_METHODS,
    DMP,
    METHODS,
    ORIGINAL_METHODS,
    AMEXConfig,
    AMEXOriginal,
    DMPConfig,
    Method,
    Track,
)
from amex.methods.base import MIN_REFERENCE_TRAVEL
from amex.plan.cache import reference_plan
from amex.plan.reference import PlanConfig, ReferencePlan

DT = 0.01
GOAL = np.array([0.384, 0.229, 0.461])
AXIS = np.array([0.0, 0.0, -1.0])
# amex's own methods only: the suite must not depend on what else is installed (plugins)
BUILTINS = {name: METHODS[name] for name in sorted(BUILTIN_METHODS)}
CLASSES = sorted(
    {*BUILTINS.values(), *ORIGINAL_METHODS.values()}, key=lambda c: f"{c.__module__}.{c.__name__}"
)
IDS = [f"{c.__module__.removeprefix('amex.methods.')}.{c.__name__}" for c in CLASSES]
AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


@pytest.fixture(scope="module")
def plan(robot):
    return reference_plan(robot, PlanConfig(), GOAL, AXIS)


def _arc(n: int = 401) -> np.ndarray:
    p = np.linspace(0.0, 1.0, n)
    u = 10 * p**3 - 15 * p**4 + 6 * p**5
    return np.stack([0.5 - 0.5 * np.cos(np.pi * u), 0.6 * np.sin(np.pi * u)], axis=1)


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_every_method_is_built_from_plan_config_period_and_robot(plan, robot, cls):
    method = cls(plan, None, DT, robot)
    assert isinstance(method, Method) and type(method.config) is cls.config_class
    assert method.reference_plan is plan and method.dt == DT and method.robot is robot
    config = cls.config_class()
    assert type(cls.from_plan(plan, config, DT, robot)) is cls  # the alias of existing callers
    assert cls(plan, config, DT, robot).config is config  # a config of its class is used as is


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
@pytest.mark.parametrize("dt", [0.0, -0.01, float("nan"), float("inf"), 8.0, "fast"])
def test_a_period_outside_the_plan_is_refused_naming_it(plan, robot, cls, dt):
    with pytest.raises(ConfigError, match=r"invalid dt=.*; valid: in \(0, T_ref = 4\] \[s\]"):
        cls(plan, None, dt, robot)


@pytest.mark.parametrize("cls", CLASSES, ids=IDS)
def test_a_malformed_reference_is_refused(plan, robot, cls):
    nan = plan.y.copy()
    nan[5, 2] = np.nan
    for y in (plan.y[:, 0], plan.y[:2], nan):
        bad = ReferencePlan(q=plan.q[: len(y)], y=y, dt=plan.dt)
        with pytest.raises(ConfigError, match=r"invalid reference plan y of shape"):
            cls(bad, None, DT, robot)


def test_a_config_with_the_same_fields_is_converted_and_another_refused(plan):
    wanted = AMEXConfig(rate_max=4.0, eq9="tangent")
    lookalike = types.SimpleNamespace(**{f.name: getattr(wanted, f.name) for f in fields(wanted)})
    assert AMEX(plan, lookalike, DT).config == wanted
    with pytest.raises(ConfigError, match=r"AMEX config DMPConfig; valid: AMEXConfig .*n_control"):
        AMEX(plan, DMPConfig(), DT)


def test_the_configs_own_checks_run_at_construction_and_in_config_validation(plan):
    with pytest.raises(ConfigError, match=r"invalid method.rate_min, rate_max=\[2.0, 1.0\]"):
        AMEX(plan, AMEXConfig(rate_min=2.0, rate_max=1.0))
    with pytest.raises(ConfigError, match=r"invalid method.eq9='midpoint'"):
        check_tree(AMEXConfig(eq9="midpoint"), "method.")  # a run's validation, before a run
    with pytest.raises(ConfigError, match=r"invalid method.quad_step=-1"):
        DMP(plan, DMPConfig(quad_step=-1))


@pytest.mark.parametrize("cls", [c for c in CLASSES if c.needs_robot], ids=lambda c: c.__name__)
def test_a_method_that_replans_joints_needs_the_robot_and_the_joint_trajectory(plan, robot, cls):
    with pytest.raises(ConfigError, match="needs the robot model"):
        cls(plan, None, DT, None)
    no_joints = r"invalid plan q shape=\[401, 0\]; valid: finite \(401, 7\)"
    with pytest.raises(ConfigError, match=no_joints):
        cls(ReferencePlan.from_path(plan.y, plan.duration), None, DT, robot)


def test_from_path_is_a_task_space_plan_over_the_duration():
    plan = ReferencePlan.from_path(_arc(), 4.0)
    assert plan.q.shape == (401, 0) and plan.duration == 4.0 and plan.dt == 0.01
    np.testing.assert_array_equal(plan.goal, _arc()[-1])
    for bad, duration in ((_arc()[:, 0], 4.0), (_arc(), 0.0), (_arc(), float("nan"))):
        with pytest.raises(ConfigError):
            ReferencePlan.from_path(bad, duration)


@pytest.mark.parametrize("cls", [AMEX, AMEXOriginal])
def test_a_reference_that_barely_moves_is_refused_by_both_amex(cls):
    still = ReferencePlan.from_path(1e-4 * _arc(), 4.0)  # 0.1 mm from start to goal
    with pytest.raises(ConfigError, match=r"the reference must move: .* 0.0001 apart; valid: >="):
        cls(still)
    cls(ReferencePlan.from_path(2 * MIN_REFERENCE_TRAVEL * _arc(), 4.0))  # 2 cm is a motion


@pytest.mark.parametrize("cls", [DMP, Track])
def test_methods_that_do_not_measure_progress_accept_a_reference_that_returns(cls):
    loop = np.sin(np.linspace(0.0, np.pi, 401))[:, None] * np.array([[0.1, 0.0]])  # out and back
    cls(ReferencePlan.from_path(loop, 4.0))


@pytest.mark.parametrize("robot_name", ["panda", "ur5"])
def test_preflight_refuses_amex_when_the_reference_goal_is_the_start(robot_name):
    """The stand-in plan then moves 3e-16 (Panda) or 1.1e-3 (UR5, its axis only): refused."""
    overrides = [f"robot={robot_name}", "task=1", "method=amex", "scenario.reference_goal=[]"]
    config = load_config([*overrides, "scenario.reference_offset=[0,0,0]"])
    with pytest.raises(ConfigError, match=r"method=amex: AMEX: the reference must move"):
        preflight(config)
    preflight(load_config(overrides))  # the default offset moves


def test_amex_run_refuses_a_reference_that_does_not_move_in_one_line(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    run_dir = tmp_path / "run"
    args = ["task=1", "method=amex", "scenario.reference_goal=[]", "episodes=1"]
    done = subprocess.run(
        [AMEX_RUN, *args, "scenario.reference_offset=[0,0,0]", f"hydra.run.dir={run_dir}"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "the reference must move" in lines[0], done.stderr
    assert not run_dir.exists()


def test_run_config_defaults_build_every_registered_method(robot):
    for name, cls in BUILTINS.items():
        config = RunConfig()
        config.method = cls.config_class()
        assert config.method.name == name
        preflight(config)
