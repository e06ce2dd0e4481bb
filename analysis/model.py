"""What the reports compute from a run's robot model, read from its ``.hydra/config.yaml``.

A run's configuration as the YAML a run wrote (:class:`analysis.sweep.Cell`), turned into the
typed sections the lower layers take (:func:`typed`): the robot, an environment of its scene, the
reference plan the run executed (from the plan cache; solved again only if the cache was
cleared, which starts no episode) and the top-down IK that checks whether a goal is reachable.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, get_args, get_origin, get_type_hints

import numpy as np

from amex.plan.cache import reference_plan
from amex.plan.reference import PlanConfig, ReferencePlan
from amex.robot import RobotConfig, RobotModel, load_robot
from amex.robot.ik import solve_ik
from amex.sim.scenario import Scenario, ScenarioConfig, make_scenario, plan_goal

from .sweep import StudyError


def typed(cls: type, data: Mapping[str, Any]) -> Any:
    """The dataclass ``cls`` from a section of a run's YAML, each value of its field's type.

    Raises:
        StudyError: a key that is not a field of ``cls`` (written by another amex version).
    """
    hints = get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise StudyError(f"{', '.join(unknown)}: not in {cls.__name__} (another amex version?)")
    return cls(**{key: _coerce(hints[key], value) for key, value in data.items()})


def _coerce(hint: Any, value: Any) -> Any:
    if dataclasses.is_dataclass(hint) and isinstance(value, Mapping):
        return typed(hint, value)  # type: ignore[arg-type]
    if get_origin(hint) is list and isinstance(value, list):
        (item,) = get_args(hint) or (Any,)
        return [_coerce(item, v) for v in value]
    if hint in (float, int, bool) and value is not None:
        return hint(value)
    return value


def robot_of(config: Mapping[str, Any]) -> RobotModel:
    """The run's robot (:func:`amex.robot.load_robot`)."""
    return load_robot(typed(RobotConfig, config["robot"]))


def start_tcp(robot: RobotModel) -> np.ndarray:
    """The TCP position at the start configuration ``q0``, shape (3,) [m] (the plan's first)."""
    return np.asarray(robot.task_position(robot.q0)[:3], dtype=float)


def scenario_of(config: Mapping[str, Any], robot: RobotModel, env: int) -> Scenario:
    """Environment ``env`` of the run's task and seed (:func:`amex.sim.scenario.make_scenario`)."""
    plan = typed(PlanConfig, config["plan"])
    return make_scenario(
        typed(ScenarioConfig, config["scenario"]),
        int(config["task"]),
        int(config["seed"]),
        env,
        start_tcp(robot),
        plan.steps * plan.dt,  # the plan's duration, as ReferencePlan computes it
    )


def reference_of(config: Mapping[str, Any], robot: RobotModel) -> ReferencePlan:
    """The reference plan the run executed, from the plan cache the run filled."""
    scenario = typed(ScenarioConfig, config["scenario"])
    goal = plan_goal(scenario, int(config["task"]), robot.tcp_pose(robot.q0).translation)
    axis = np.asarray(scenario.goal_axis, dtype=float)
    return reference_plan(robot, typed(PlanConfig, config["plan"]), goal, axis)


def reach_errors(config: Mapping[str, Any], envs: list[int]) -> list[float]:
    """Top-down IK position error [m] of each environment's final goal (0: reachable)."""
    robot = robot_of(config)
    out = []
    for env in envs:
        scenario = scenario_of(config, robot, env)
        goal = scenario.goal_at(math.inf)
        out.append(solve_ik(robot, goal, scenario.goal_axis).position_error)
    return out
