import math

import numpy as np
import pytest

from amex.config import RunConfig
from amex.episode import run_episode
from amex.interfaces import Command
from amex.methods import Track, TrackConfig
from amex.runner import prepare, run_one
from amex.scenario import make_scenario


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
    scenario = make_scenario(config.scenario, 0, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = method_cls.from_plan(ctx.plan, config.method, 0.01)
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
