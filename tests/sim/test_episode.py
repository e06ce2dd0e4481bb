import dataclasses
import math

import numpy as np
import pytest

from amex.control.osc import OperationalSpaceController
from amex.control.state import RobotState
from amex.core.errors import ConfigError
from amex.core.types import Command
from amex.experiment.config import RunConfig, validate
from amex.experiment.runner import prepare, run_one
from amex.methods import Track, TrackConfig
from amex.sim.episode import run_episode
from amex.sim.scenario import make_scenario


@pytest.fixture(scope="module")
def context():
    config = RunConfig()
    config.method = TrackConfig()
    return config, prepare(config)


def test_reference_plan_reaches_the_reference_goal(context):
    _, ctx = context
    assert ctx.plan.y.shape == (401, 6)
    assert np.linalg.norm(ctx.plan.y[-1, :3] - [0.384, 0.229, 0.461]) < 2e-3
    assert np.allclose(ctx.plan.y[-1, 3:], [0, 0, -1], atol=1e-2)


def test_track_succeeds_in_task0_near_the_plan_duration(context):
    config, ctx = context
    result = run_one(config, ctx, 0)
    assert result.success and not result.failure and not result.collided
    assert 3.6 <= result.final_time <= 4.4
    assert result.final_distance <= config.loop.stop_radius
    assert result.sum_sq_acc > 0 and result.compute_time_median > 0


def test_track_misses_an_offset_goal(context):
    config, ctx = context
    config.task = 1
    try:
        result = run_one(config, ctx, 0)
    finally:
        config.task = 0
    assert not result.success and result.final_time == pytest.approx(config.max_time)


class _NaNMethod(Track):
    name = "nan"

    def step(self, obs):
        return Command(y=np.full(6, np.nan), yd=np.zeros(6))


class _Wild(Track):
    name = "wild"

    def step(self, obs):
        return Command(y=obs.y + np.r_[50.0, 50.0, 50.0, 0, 0, 0], yd=np.full(6, 1e4))


@pytest.mark.parametrize(("method_cls", "reason"), [(_NaNMethod, "nan_command"), (_Wild, "")])
def test_numerical_trouble_ends_the_episode_with_a_reason(context, method_cls, reason):
    config, ctx = context
    scenario = make_scenario(config.scene(), 0, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = method_cls(ctx.plan, config.method, 0.01)
    result = run_episode(ctx.robot, method, scenario, config.gains(), config.loop)
    assert not result.success
    if reason:
        assert result.failure == reason
        assert result.final_time == 0.0
    else:  # torques are clipped: the arm moves fast but the episode ends with a recorded state
        assert math.isfinite(result.final_distance)


def test_obstacle_contact_is_detected_and_avoided_with_the_collision_task(context):
    config, ctx = context
    config.task = 3
    weight = config.controller.col.weight
    try:
        with_avoidance = [run_one(config, ctx, env) for env in range(3)]
        config.controller.col.weight = 0.0  # blind controller: tracking hits the obstacle
        blind = [run_one(config, ctx, env) for env in range(3)]
    finally:
        config.task = 0
        config.controller.col.weight = weight
    assert any(r.collided for r in blind)
    assert sum(r.collided for r in with_avoidance) < sum(r.collided for r in blind)


class _Recorder:
    def __init__(self):
        self.steps = []

    def record(self, step):
        self.steps.append(step)

    def finish(self, result):
        self.result = result


def test_kinematic_simulation_integrates_the_controller_accelerations_by_explicit_euler(context):
    config, ctx = context
    loop = dataclasses.replace(config.loop, kinematic=True, max_time=0.5)
    scenario = make_scenario(config.scene(), 0, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = Track(ctx.plan, config.method, 0.01)
    recorder = _Recorder()
    run_episode(ctx.robot, method, scenario, config.gains(), loop, recorder)
    first, second = recorder.steps[0], recorder.steps[1]
    # one outer step = 10 inner steps of q += dt v, v += dt qdd*, with qdd* the OSC's solution
    osc = OperationalSpaceController(ctx.robot, config.gains())
    q, v = first.state.q.copy(), first.state.v.copy()
    data = ctx.robot.model.createData()
    for _ in range(10):
        qdd = osc.accelerations(RobotState(ctx.robot, data, q.copy(), v.copy()), first.command)
        q, v = q + 1e-3 * v, v + 1e-3 * qdd
    np.testing.assert_array_equal(second.state.q, q)
    np.testing.assert_array_equal(second.state.v, v)
    assert not np.any(first.tau)  # nothing is actuated


def test_kinematic_and_dynamic_simulations_agree_on_a_free_motion(context):
    config, ctx = context
    config.sim = "kinematic"
    try:
        kinematic = run_one(config, ctx, 0)
    finally:
        config.sim = "dynamic"
    dynamic = run_one(config, ctx, 0)
    assert kinematic.success and dynamic.success
    assert abs(kinematic.final_time - dynamic.final_time) <= 0.02
    assert kinematic.sum_sq_acc == pytest.approx(dynamic.sum_sq_acc, rel=0.05)


def test_kinematic_simulation_still_detects_obstacle_contact(context):
    config, ctx = context
    config.task, config.sim = 3, "kinematic"
    weight = config.controller.col.weight
    config.controller.col.weight = 0.0  # blind: tracking passes through the obstacle
    try:
        blind = [run_one(config, ctx, env) for env in range(3)]
    finally:
        config.task, config.sim = 0, "dynamic"
        config.controller.col.weight = weight
    assert any(r.collided for r in blind)


def test_a_kinematic_simulation_refuses_a_model_mismatch():
    config = RunConfig(sim="kinematic")
    config.method = TrackConfig()
    config.mismatch.mass_scale = 1.2
    with pytest.raises(ConfigError, match="with sim=kinematic"):
        validate(config)
