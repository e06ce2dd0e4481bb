"""Continuous replanning (CR): replanned knots, warm starts, horizon rules, failures, episodes.

Real optimizer, real MuJoCo and Pinocchio; the ``robot`` fixture comes from ``conftest.py``.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from amex.control.collision import CollisionModel
from amex.core.errors import ConfigError, InputError, SolverError
from amex.core.scaling import to_scene_units
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one, setup
from amex.methods import CR, METHODS, CRConfig
from amex.methods.base import Observation
from amex.plan.knots import resample_knots, shift_warm_start
from amex.plan.optimizer import TrajectoryProblem, solve_trajectory
from amex.plan.weights import CostWeights
from amex.sim.episode import run_episode
from amex.sim.scenario import make_scenario

DT = 0.01  # outer period [s]


def scene(config: CRConfig) -> CRConfig:
    """``config`` in the Panda scene's units (lengths stated in original units x 0.2)."""
    return to_scene_units(config, RunConfig().scenario.scale)


@pytest.fixture(scope="module")
def context():
    config = RunConfig()
    config.method = CRConfig()
    return config, prepare(config)


def reference_weights(config: RunConfig, **changes) -> CRConfig:
    """CR with exactly the reference plan's cost weights (no collision term)."""
    p = config.plan
    weights = {f.name: getattr(p, f.name) for f in dataclasses.fields(CostWeights)}
    weights.update(collision=0.0, knot_dt=p.dt)
    return CRConfig(**{**weights, **changes})


def observe(config, t, q, qd, goal_pos=None, obstacles=None, radii=None) -> Observation:
    goal_pos = config.scenario.reference_goal if goal_pos is None else goal_pos
    goal = np.concatenate([goal_pos, config.scenario.goal_axis]).astype(float)
    return Observation(
        t=t,
        q=np.asarray(q, dtype=float),
        qd=np.asarray(qd, dtype=float),
        y=np.zeros(6),
        yd=np.zeros(6),
        goal=goal,
        obstacles=np.zeros((0, 3)) if obstacles is None else obstacles,
        obstacle_radii=np.zeros(0) if radii is None else radii,
    )


def min_clearance(robot, centers, radii, knots) -> float:
    """Smallest arm-obstacle surface distance over the knots, by coal (not the optimizer's)."""
    model = CollisionModel(robot, radii)
    model.set_obstacles(centers)
    data = robot.model.createData()
    distances = []
    for q in knots:
        pin.forwardKinematics(robot.model, data, q)
        distances.append(model.min_distance(data))
    return min(distances)


def test_cr_is_registered_with_its_config():
    assert METHODS["cr"] is CR and CR.config_class is CRConfig
    assert (Path(__file__).resolve().parents[2] / "conf" / "method" / "cr.yaml").exists()


def test_replanning_from_the_reference_start_reproduces_the_reference(context):
    config, ctx = context
    plan = ctx.plan
    cr = CR(plan, reference_weights(config), DT, ctx.robot)
    obs = observe(config, 0.0, plan.q[0], np.zeros(7))
    cr.reset(obs)
    command = cr.step(obs)
    assert cr.status.mode == "shrink" and cr.status.steps == len(plan.q) - 1
    np.testing.assert_allclose(cr.knots[1], plan.q[1], atol=1e-6)  # the reference's next knot
    np.testing.assert_allclose(cr.knots, plan.q, atol=1e-4)
    np.testing.assert_allclose(command.q, (plan.q[0] + plan.q[1]) / 2, atol=1e-6)  # at t + dt/2
    np.testing.assert_allclose(command.qd, (plan.q[1] - plan.q[0]) / DT, atol=1e-4)
    assert command.y is None and command.yd is None


def test_warm_start_converges_in_fewer_iterations_than_cold(context):
    config, ctx = context
    plan, robot = ctx.plan, ctx.robot
    goal = np.asarray(config.scenario.reference_goal) + [0.03, -0.04, 0.05]  # a new goal
    cr = CR(plan, scene(CRConfig(tolerance=1e-4)), DT, robot)
    first = observe(config, 0.0, plan.q[0], np.zeros(7), goal)
    cr.reset(first)
    cr.step(first)
    q1 = cr.knots[1].copy()
    v1 = (cr.knots[1] - cr.knots[0]) / DT
    second = observe(config, DT, q1, v1, goal)
    cr.step(second)
    warm = cr.status
    problem = TrajectoryProblem(q1, v1, warm.steps, DT, goal, second.goal[3:], costs=cr.costs)
    cold = solve_trajectory(robot, problem, tolerance=1e-4)
    assert warm.converged and cold.converged
    assert warm.iterations < cold.iterations
    assert warm.cost <= cold.cost * (1 + 1e-3)


def test_horizon_shrinks_to_t_ref_then_holds_then_recedes(context):
    config, ctx = context
    cr = CR(ctx.plan, scene(CRConfig()), DT, ctx.robot)
    assert cr.horizon(0.0) == ("shrink", 400)
    assert cr.horizon(1.234) == ("shrink", 277)
    assert cr.horizon(3.98) == ("shrink", 2)  # min_steps = 2 (original)
    assert cr.horizon(3.99) == ("hold", 0)
    assert cr.horizon(4.0) == ("tail", 50) and cr.horizon(8.0) == ("tail", 50)
    original = CR(ctx.plan, scene(CRConfig(tail_horizon=0.0)), DT, ctx.robot)
    assert original.horizon(4.0) == ("hold", 0) and original.horizon(9.0) == ("hold", 0)


def test_hold_sends_the_last_final_knot_at_rest(context):
    config, ctx = context
    plan = ctx.plan
    cr = CR(plan, scene(CRConfig()), DT, ctx.robot)
    obs = observe(config, 3.98, plan.q[398], (plan.q[399] - plan.q[397]) / (2 * DT))
    cr.reset(obs)
    cr.step(obs)
    final = cr.knots[-1].copy()
    command = cr.step(dataclasses.replace(obs, t=3.99))
    assert cr.status.mode == "hold" and cr.status.iterations == 0
    np.testing.assert_array_equal(command.q, final)
    np.testing.assert_array_equal(command.qd, np.zeros(7))


def test_after_t_ref_the_tail_replans_towards_a_moved_goal(context):
    config, ctx = context
    robot, plan = ctx.robot, ctx.plan
    goal = np.asarray(config.scenario.reference_goal) + [0.0, 0.03, 0.0]
    cr = CR(plan, scene(CRConfig()), DT, robot)
    obs = observe(config, 4.5, plan.q[-1], np.zeros(7), goal)
    cr.reset(obs)
    command = cr.step(obs)
    assert cr.status.mode == "tail" and cr.status.steps == 50
    assert np.linalg.norm(robot.task_position(cr.knots[-1])[:3] - goal) < 5e-3  # from 3 cm
    np.testing.assert_array_equal(command.q, cr.knots[-1])  # the tail's target: its final knot
    np.testing.assert_array_equal(command.qd, np.zeros(7))


def test_plan_keeps_out_of_the_obstacle_margin_in_a_task3_scene(context):
    config, ctx = context
    robot, plan = ctx.robot, ctx.plan
    scenario = make_scenario(config.scene(), 3, 0, 0, plan.y[0, :3], plan.duration)
    centers, radii = scenario.obstacles_at(0.0), scenario.obstacle_radii
    obs = observe(config, 0.0, plan.q[0], np.zeros(7), scenario.goal_at(0.0), centers, radii)
    cr = CR(plan, scene(CRConfig()), DT, robot)
    cr.reset(obs)
    cr.step(obs)
    margin = cr.costs.weights.collision_margin
    assert min_clearance(robot, centers, radii, plan.q) < 0.0  # the reference runs through it
    assert min_clearance(robot, centers, radii, cr.knots) >= margin - 2e-3
    final_tcp = robot.task_position(cr.knots[-1])[:3]
    assert np.linalg.norm(final_tcp - scenario.goal_at(0.0)) < 5e-3


def test_realtime_mode_caps_the_iterations(context):
    config, ctx = context
    plan = ctx.plan
    scenario = make_scenario(config.scene(), 3, 0, 0, plan.y[0, :3], plan.duration)
    obs = observe(
        config,
        0.0,
        plan.q[0],
        np.zeros(7),
        scenario.goal_at(0.0),
        scenario.obstacles_at(0.0),
        scenario.obstacle_radii,
    )
    full = CR(plan, scene(CRConfig()), DT, ctx.robot)
    capped = scene(CRConfig(realtime=True, realtime_iterations=2))
    realtime = CR(plan, capped, DT, ctx.robot)
    for cr in (full, realtime):
        cr.reset(obs)
        cr.step(obs)
    assert full.status.iterations > 2
    assert realtime.status.iterations == 2 and not realtime.status.converged
    assert realtime.status.cost >= full.status.cost


def test_internals_report_the_solve_and_the_planned_tcp_path(context):
    config, ctx = context
    robot, plan = ctx.robot, ctx.plan
    cr = CR(plan, scene(CRConfig()), DT, robot)
    obs = observe(config, 0.5, plan.q[50], (plan.q[51] - plan.q[49]) / (2 * DT))
    cr.reset(obs)
    cr.step(obs)
    info = cr.internals()
    assert info["mode"] == "shrink" and info["steps"] == 350
    assert info["iterations"] >= 1 and info["converged"] and np.isfinite(info["cost"])
    path = info["plan"]
    assert path.shape == (351, 3)
    for k in (0, 100, 350):
        np.testing.assert_allclose(path[k], robot.task_position(cr.knots[k])[:3], atol=1e-12)


def test_internals_compute_the_planned_path_only_when_read_and_keep_their_step(context):
    """``plan`` is lazy (no kinematics for a step nobody logs) and a late read is its own step's."""
    config, ctx = context
    robot, plan = ctx.robot, ctx.plan
    cr = CR(plan, scene(CRConfig()), DT, robot)
    obs = observe(config, 0.5, plan.q[50], (plan.q[51] - plan.q[49]) / (2 * DT))
    cr.reset(obs)
    cr.step(obs)
    calls = []
    kinematics = cr.kinematics

    class Counting:
        def frame_positions(self, q, frame_id):
            calls.append(len(q))
            return kinematics.frame_positions(q, frame_id)

    cr.kinematics = Counting()
    info, knots = cr.internals(), cr.knots.copy()
    assert "plan" in info and len(info) == 7 and not calls
    later = observe(config, 0.6, plan.q[60], (plan.q[61] - plan.q[59]) / (2 * DT))
    cr.step(later)  # a new solve: a new plan
    captured = {k: v for k, v in info.items()}  # the log's capture reads every item
    assert calls == [351]
    expected = kinematics.frame_positions(knots, robot.tcp_frame_id)
    assert np.array_equal(captured["plan"], expected) and info["plan"] is captured["plan"]
    assert calls == [351]  # computed once
    assert pickle.loads(pickle.dumps(info)).keys() == info.keys()


def test_non_finite_observation_raises_solver_error(context):
    config, ctx = context
    cr = CR(ctx.plan, scene(CRConfig()), DT, ctx.robot)
    q = ctx.plan.q[0].copy()
    q[3] = np.nan
    with pytest.raises(InputError, match="non-finite q"):  # rejected where it enters
        observe(config, 0.0, q, np.zeros(7))
    obs = observe(config, 0.0, ctx.plan.q[0].copy(), np.zeros(7))
    cr.reset(obs)
    obs.q[3] = np.nan  # changed after the observation's check: the solver refuses it too
    with pytest.raises(SolverError, match="non-finite q_start") as info:
        cr.step(obs)
    assert isinstance(info.value.problem, TrajectoryProblem)


class _BlindAfterHalfASecond(CR):
    """CR whose goal measurement turns to NaN at t = 0.05 s."""

    def step(self, obs):
        if obs.t >= 0.05:
            obs = dataclasses.replace(obs, goal=np.full(6, np.nan))
        return super().step(obs)


def test_solver_failure_ends_the_episode_with_a_solver_reason(context):
    config, ctx = context
    scenario = make_scenario(config.scene(), 1, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = _BlindAfterHalfASecond(ctx.plan, scene(CRConfig()), DT, ctx.robot)
    result = run_episode(ctx.robot, method, scenario, config.gains(), config.loop)
    assert result.failure.startswith("solver") and "non-finite goal" in result.failure
    assert not result.success
    assert result.final_time == pytest.approx(0.05)


def test_invalid_settings_raise_config_error(context):
    config, ctx = context
    with pytest.raises(ConfigError, match="robot"):
        CR(ctx.plan, scene(CRConfig()), DT, None)
    bad = [
        {"max_iterations": 0},
        {"realtime_iterations": 0},
        {"min_steps": 0},
        {"knot_dt": 0.0},
        {"tail_horizon": -1.0},
        {"damping": 0.0},
        {"collision_margin": 0.0},
        {"final_position": -1.0},
    ]
    for changes in bad:
        with pytest.raises(ConfigError, match=next(iter(changes))):
            CR(ctx.plan, scene(CRConfig(**changes)), DT, ctx.robot)


def test_resampling_whole_knots_is_the_shifted_warm_start():
    rng = np.random.default_rng(0)
    knots = rng.standard_normal((11, 7))
    np.testing.assert_array_equal(resample_knots(knots, 1.0, 1.0, 10), shift_warm_start(knots, 9))
    np.testing.assert_array_equal(resample_knots(knots, 1.0, 1.0, 14), shift_warm_start(knots, 13))
    half = resample_knots(knots, 0.5, 2.0, 3)  # rows at 0.5, 2.5, 4.5
    np.testing.assert_allclose(half, (knots[[0, 2, 4]] + knots[[1, 3, 5]]) / 2, atol=1e-15)


@pytest.mark.parametrize(("task", "env"), [(0, 0), (3, 0)])
def test_cr_episodes_reach_the_goal_without_contact(context, task, env):
    config, ctx = context
    config = dataclasses.replace(config, task=task, max_time=6.0)
    result = run_one(config, ctx, env)
    assert result.success and not result.failure and not result.collided
    assert result.final_time < 4.5
    assert 0.0 < result.compute_time_median < 0.1


def test_amex_run_task3_with_cr(tmp_path):
    out = tmp_path / "run"
    env = dict(os.environ)
    env.pop("AMEX_DEBUG", None)
    proc = subprocess.run(
        [
            str(Path(sys.executable).parent / "amex-run"),
            "task=3",
            "method=cr",
            "episodes=2",
            "max_time=6",
            f"hydra.run.dir={out}",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    with open(out / "episodes.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["method"] for r in rows] == ["cr", "cr"]
    assert all(r["success"] == "1" and not r["failure"] for r in rows)


@pytest.mark.parametrize("task", [2, 3])
def test_the_one_call_step_commands_as_the_solver_path(context, task):
    """CR's usual step (ReplanLoop: the solve and its target in one call) is solve_trajectory's.

    The same observations, one CR on each path: the same commands and statuses, bit for bit.
    """
    config, ctx = context
    run = setup(dataclasses.replace(config, task=task, max_time=1.5), ctx)
    one_call = run.method(ctx.plan, run.params, run.outer_dt, ctx.robot)
    solver_path = run.method(ctx.plan, run.params, run.outer_dt, ctx.robot)
    solver_path.replan_loop = None
    assert one_call.replan_loop is not None
    steps, taken = one_call.step, []

    def step(obs):
        command = steps(obs)
        taken.append((obs, command, one_call.status))
        return command

    one_call.step = step
    scenario = make_scenario(run.scene, task, run.seed, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    run_episode(ctx.robot, one_call, scenario, run.gains, run.loop)
    assert len(taken) > 100
    for obs, command, status in taken:
        again = solver_path.step(obs)
        assert np.array_equal(again.q, command.q) and np.array_equal(again.qd, command.qd)
        assert solver_path.status[:5] == status[:5] or math.isnan(status.cost)
    assert np.array_equal(solver_path.knots, one_call.knots)
