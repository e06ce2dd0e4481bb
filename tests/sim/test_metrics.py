"""Metrics: the paper's smoothness figure as the authors computed it, and a rate-free one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.methods import TrackConfig
from amex.sim.metrics import paper_sum_sq_acc, round_significant


def test_round_significant_writes_like_printf_g():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.normal(scale=3.0, size=200), [0.0, 1.0, -2.5, 123456.7, 1e-7]])
    expected = np.array([float(f"{v:.6g}") for v in x])
    np.testing.assert_array_equal(round_significant(x), expected)


def test_paper_sum_sq_acc_differentiates_like_matlab_gradient_twice():
    dt = 1e-3
    t = np.arange(0.0, 1.0, dt)
    q = np.stack([0.3 * t**2, 0.1 * t**3], axis=1)  # exact: qdd = (0.6, 0.6 t)
    first = np.empty_like(q)  # MATLAB: one-sided at the ends, central inside
    first[0], first[-1] = (q[1] - q[0]) / dt, (q[-1] - q[-2]) / dt
    first[1:-1] = (q[2:] - q[:-2]) / (2 * dt)
    second = np.empty_like(q)
    second[0], second[-1] = (first[1] - first[0]) / dt, (first[-1] - first[-2]) / dt
    second[1:-1] = (first[2:] - first[:-2]) / (2 * dt)
    assert paper_sum_sq_acc(q, dt, digits=17) == pytest.approx(np.sum(second**2), rel=1e-12)


def test_rounding_to_six_digits_dominates_a_smooth_motion_at_1khz():
    dt = 1e-3
    t = np.arange(0.0, 4.0, dt)[:, None]
    q = 1.5 + 0.2 * np.sin(np.pi * t / 4.0) * np.ones((1, 7))  # |q| > 1 rad on 7 joints
    exact = paper_sum_sq_acc(q, dt, digits=17)
    paper = paper_sum_sq_acc(q, dt)
    assert exact == pytest.approx(213.0, rel=0.01)  # a slow sine: qdd ~ 0.12 rad/s^2
    # 6 digits of 1.5 rad: steps of 1e-5 rad, a second difference of ~1-10 rad/s^2 at 1 ms
    assert paper > 100 * exact


@pytest.fixture(scope="module")
def context():
    config = RunConfig()
    config.method = TrackConfig()
    return config, prepare(config)


def test_int_sq_acc_does_not_depend_on_the_simulation_rate(context):
    config, ctx = context
    base = run_one(config, ctx, 0)
    config.inner_hz = 2000.0
    try:
        fast = run_one(config, ctx, 0)
    finally:
        config.inner_hz = 1000.0
    assert fast.sum_sq_acc == pytest.approx(2.0 * base.sum_sq_acc, rel=0.05)
    assert fast.int_sq_acc == pytest.approx(base.int_sq_acc, rel=0.05)
    assert base.int_sq_acc == pytest.approx(base.sum_sq_acc * 1e-3)
    assert base.sum_sq_acc_paper > base.sum_sq_acc


def test_a_state_lag_of_one_step_changes_an_episode_only_slightly(context):
    config, ctx = context
    base = run_one(config, ctx, 0)
    config.state_lag = True
    try:
        lagging = run_one(config, ctx, 0)
    finally:
        config.state_lag = False
    assert lagging.success and lagging.final_time >= base.final_time
    assert lagging.final_time - base.final_time <= 0.01


def test_plan_fidelity_is_zero_on_the_reference_and_the_distance_off_it():
    from amex.sim.metrics import plan_fidelity

    s = np.linspace(0.0, 1.0, 401)[:, None]
    ref = np.hstack([0.3 * s, 0.1 * np.sin(np.pi * s), 0.0 * s])
    assert plan_fidelity(ref[::4], ref, ref[-1]) == pytest.approx(0.0, abs=1e-12)
    goal = ref[-1] + [0.0, 0.0, 0.05]  # the goal ended 5 cm higher: the shape moves with it
    moved = ref + s * (goal - ref[-1])
    assert plan_fidelity(moved[::4], ref, goal) == pytest.approx(0.0, abs=1e-12)
    off = ref[::4] + [0.0, 0.0, 0.01]  # 1 cm above the unmoved path, which stays the shape
    assert plan_fidelity(off, ref, ref[-1]) == pytest.approx(0.01, rel=1e-6)


def test_the_final_axis_error_is_the_angle_between_the_axes():
    from amex.sim.metrics import axis_error

    assert axis_error([0, 0, -1], [0, 0, -1]) == 0.0
    assert axis_error([1, 0, 0], [0, 0, -1]) == pytest.approx(np.pi / 2)
    assert np.isnan(axis_error([np.nan, 0, 0], [0, 0, 1]))


def test_the_new_metrics_come_with_every_episode(context):
    config, ctx = context
    result = run_one(config, ctx, 0)
    assert result.path_length > 0.0 and result.plan_fidelity >= 0.0
    assert 0.0 <= result.final_axis_error < 0.1 and np.isnan(result.min_clearance)  # Task 0
    assert result.compute_cpu_median >= 0.0 and result.deadline_misses == 0.0


def test_deadline_misses_count_the_steps_over_the_period_on_cpu_time(context):
    import time

    from amex.methods import Method
    from amex.sim.episode import run_episode
    from amex.sim.scenario import make_scenario

    config, ctx = context

    class Busy(Method):  # burns 15 ms of CPU on every other step, sleeps 15 ms on the rest
        name = "busy"

        def __init__(self):
            self.k = 0
            self.target = ctx.plan.y[-1].copy()

        @classmethod
        def from_plan(cls, plan, config, dt, robot=None):  # pragma: no cover
            raise NotImplementedError

        def reset(self, obs):
            pass

        def step(self, obs):
            self.k += 1
            end = time.thread_time() + 0.015
            if self.k % 2:
                while time.thread_time() < end:
                    pass
            else:
                time.sleep(0.015)  # wall time, no CPU: no deadline missed
            from amex.core.types import Command

            return Command(y=self.target, yd=np.zeros(6))

    loop = dataclasses.replace(config.loop, max_time=0.2)
    scenario = make_scenario(config.scene(), 0, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    result = run_episode(ctx.robot, Busy(), scenario, config.gains(), loop)
    assert result.deadline_misses == pytest.approx(0.5, abs=0.06)
    assert result.compute_time_median > 0.01  # wall time counts the sleeps too
    assert result.compute_cpu_max >= result.compute_cpu_p95 >= 0.015  # the burning half
    assert math.isnan(result.budget_stops)  # no time budget of its own
