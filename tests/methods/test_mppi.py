"""MPPI: the weights, the warm start's shift, the budget, the seeding, the command and episodes.

Real robot, planner, MuJoCo and Pinocchio (the ``robot`` fixture of ``conftest.py``).
"""

from __future__ import annotations

import csv
import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from amex.core.errors import ConfigError, InputError
from amex.core.scaling import to_scene_units
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare
from amex.methods import METHODS, MPPI, MPPIConfig
from amex.methods.base import Observation
from amex.methods.mppi import (
    interpolation_matrix,
    observation_words,
    pd_period,
    shift_controls,
    softmax_weights,
)
from amex.sim.episode import run_episode
from amex.sim.metrics import TIMING_COLUMNS
from amex.sim.scenario import make_scenario

DT = 0.01
AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


def scene(config: MPPIConfig) -> MPPIConfig:
    """``config`` in the Panda scene's units (the collision margin x 0.2)."""
    return to_scene_units(config, RunConfig().scenario.scale)


@pytest.fixture(scope="module")
def context():
    config = RunConfig()
    config.method = scene(MPPIConfig())
    return config, prepare(config)


def observe(robot, t, q, qd=None, goal=None, obstacles=None) -> Observation:
    q = np.asarray(q, dtype=float)
    y = robot.task_position(q)
    goal = y + [0.05, 0.1, -0.05, 0.0, 0.0, 0.0] if goal is None else goal
    obstacles = np.zeros((0, 3)) if obstacles is None else obstacles
    return Observation(
        t=t,
        q=q,
        qd=np.zeros(len(q)) if qd is None else qd,
        y=y,
        yd=np.zeros(6),
        goal=np.asarray(goal, dtype=float),
        obstacles=obstacles,
        obstacle_radii=np.full(len(obstacles), 0.02),
    )


def test_mppi_is_registered_under_its_module_name():
    assert METHODS["mppi"] is MPPI and MPPI.config_class().name == "mppi"


# ----------------------------------------------------------------------------- pieces
def test_the_interpolation_is_linear_through_the_control_points():
    B = interpolation_matrix(16, 2)
    assert B.shape == (16, 9)
    np.testing.assert_allclose(B.sum(axis=1), 1.0)
    points = 3.0 - 0.5 * np.arange(9)  # a linear function of the control index
    midpoints = (np.arange(16) + 0.5) / 2
    np.testing.assert_allclose(B @ points, 3.0 - 0.5 * midpoints)
    assert interpolation_matrix(5, 2).shape == (5, 4)  # ceil(5 / 2) + 1 points cover 5 intervals


def test_the_warm_start_shift_reads_the_sequence_later_and_falls_to_zero_beyond_it():
    rng = np.random.default_rng(0)
    controls = rng.standard_normal((5, 7))
    np.testing.assert_array_equal(shift_controls(controls, 0.0), controls)
    shifted = shift_controls(controls, 2.0)
    np.testing.assert_array_equal(shifted[:3], controls[2:])
    np.testing.assert_array_equal(shifted[3:], 0.0)
    line = np.outer(np.arange(5.0), np.ones(7))  # linear: a fractional shift is exact
    np.testing.assert_allclose(shift_controls(line, 0.25)[:4], line[:4] + 0.25)
    np.testing.assert_allclose(shift_controls(line, 0.25)[4], 0.75 * 4.0)  # towards zero


def test_the_weights_sum_to_one_favour_the_cheapest_and_ignore_the_cost_scale():
    rng = np.random.default_rng(1)
    costs = rng.random(64) * 10.0
    w = softmax_weights(costs, 0.1)
    assert w.sum() == pytest.approx(1.0) and np.argmax(w) == np.argmin(costs)
    np.testing.assert_allclose(softmax_weights(3.0 * costs + 7.0, 0.1), w)  # relative temperature
    assert (np.diff(w[np.argsort(costs)]) <= 0).all()  # cheaper, heavier
    np.testing.assert_array_equal(softmax_weights(np.full(4, 2.0), 0.1), [1.0, 0.0, 0.0, 0.0])
    hot, cold = softmax_weights(costs, 10.0), softmax_weights(costs, 0.01)
    assert 1 / (hot @ hot) > 1 / (w @ w) > 1 / (cold @ cold)  # effective samples


@pytest.mark.parametrize("kp, kd", [(100.0, 100.0), (400.0, 40.0), (0.0, 50.0)])
def test_the_matched_command_ends_the_period_at_the_nominals_velocity(robot, context, kp, kd):
    """Simulated with the joint PD itself: Euler at 1 kHz over the 10 ms period."""
    config, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig(tracking_kp=kp, tracking_kd=kd)), DT, robot)
    rng = np.random.default_rng(2)
    method.controls = rng.standard_normal(method.controls.shape)
    q_start, v_start = robot.q0 + 0.1 * rng.standard_normal(7), rng.standard_normal(7)
    q_star, qd_star = method.target(q_start, v_start)
    q, v = q_start, v_start
    for _ in range(10):
        q, v = q + 1e-3 * v, v + 1e-3 * (kp * (q_star - q) + kd * (qd_star - v))
    u0, slope = method.controls[0], (method.controls[1] - method.controls[0]) / method.control_dt
    np.testing.assert_allclose(v, v_start + u0 * DT + slope * DT**2 / 2, atol=1e-12)
    midpoint = MPPI(ctx.plan, scene(MPPIConfig(command="midpoint")), DT, robot)
    midpoint.controls = method.controls
    q_mid, qd_mid = midpoint.target(q_start, v_start)  # CR's: the nominal's midpoint and chord
    np.testing.assert_allclose(qd_mid, v_start + u0 * DT / 2 + slope * DT**2 / 6, atol=1e-12)


def test_the_pd_period_map_is_the_pd_simulated():
    (a_q, a_v), b = pd_period(100.0, 100.0, 1e-3, 10)
    q, v, r = 0.3, -0.7, 2.0  # r = kp q* + kd q_dot*
    for _ in range(10):
        q, v = q + 1e-3 * v, v + 1e-3 * (r - 100.0 * q - 100.0 * v)
    assert v == pytest.approx(a_q * 0.3 + a_v * -0.7 + b * r, abs=1e-14)


def test_the_observation_digest_sees_every_number():
    from amex.core.types import Observation as Obs

    obs = Obs(0.5, np.zeros(7), np.zeros(7), np.zeros(6), np.zeros(6), np.ones(6))
    words = observation_words(obs)
    assert len(words) == 4 and words == observation_words(dataclasses.replace(obs))
    for name in ("t", "q", "qd", "y", "yd", "goal"):
        value = getattr(obs, name)
        changed = value + 1e-12 if name == "t" else value.copy()
        if name != "t":
            changed[-1] += 1e-12
        assert observation_words(dataclasses.replace(obs, **{name: changed})) != words, name


# ----------------------------------------------------------------------------- state
def test_without_noise_the_warm_start_is_the_last_solution_shifted(robot, context):
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig(noise=0.0)), DT, robot)
    method.reset(observe(robot, 0.0, robot.q0))
    method.step(observe(robot, 0.0, robot.q0))
    first = method.controls.copy()
    np.testing.assert_array_equal(first[0], method.reference_acc[0])  # the plan's first
    method.step(observe(robot, DT, robot.q0))
    np.testing.assert_allclose(method.controls, shift_controls(first, DT / method.control_dt))
    assert method.status.evaluated == MPPIConfig().samples


def test_sampling_lowers_the_cost_of_the_warm_start(robot, context):
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig()), DT, robot)
    obs = observe(robot, 0.0, robot.q0)
    method.reset(obs)
    costs = []
    for _k in range(15):
        method.step(dataclasses.replace(obs, t=0.0))  # the same state: an optimization
        costs.append(method.status.warm_cost)
        method.t_controls = 0.0
    assert costs[-1] < 0.5 * costs[0]
    assert method.status.best_cost <= method.status.warm_cost


def test_a_tiny_budget_returns_in_time_and_records_the_early_stop(robot, context):
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig(budget=1e-5, samples=4096)), DT, robot)
    obs = observe(robot, 0.0, robot.q0, obstacles=robot.task_position(robot.q0)[None, :3] + 0.1)
    method.reset(obs)
    before = method.controls.copy()
    command = method.step(obs)  # 4096 rollouts would take ~30 ms: never within 10 us
    s = method.status
    assert s.early_stop and s.evaluated < 4096 and method.early_stops == 1
    assert method.internals()["early_stop"] and method.internals()["early_stops"] == 1
    if s.evaluated == 0:  # nothing evaluated: the warm start is sent as it is
        np.testing.assert_array_equal(method.controls, before)
    assert np.isfinite(command.q).all() and np.isfinite(command.qd).all()
    method.step(dataclasses.replace(obs, t=DT))
    assert method.early_stops == 2
    method.reset(obs)
    assert method.early_stops == 0


def test_one_slow_chunk_does_not_stop_the_steps_after_it_for_good(robot, context):
    """A chunk estimate beyond the budget halves with every step it stops, until chunks fit."""
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig()), DT, robot)
    obs = observe(robot, 0.0, robot.q0)
    method.reset(obs)
    method._chunk_time = int(0.04e9)  # as if the last chunk had taken 40 ms (a page fault)
    evaluated = []
    for k in range(6):
        method.step(dataclasses.replace(obs, t=k * DT))
        evaluated.append(method.status.evaluated)
    assert evaluated[:3] == [0, 0, 0] and evaluated[-1] == MPPIConfig().samples


def test_the_work_clock_stops_at_the_sample_its_model_predicts_and_repeats_bit_for_bit(
    robot, context
):
    """``budget_clock=work``: where the budget binds, it binds at the same sample every time."""
    from amex.methods.mppi import WORK_NS_KNOT, WORK_NS_PAIR, WORK_NS_TAIL

    _, ctx = context
    config = scene(MPPIConfig(budget_clock="work", samples=4096, chunk=32, budget=DT))
    obstacles = robot.task_position(robot.q0)[None, :3] + 0.1
    per_sample = config.knots * (WORK_NS_KNOT + WORK_NS_PAIR * len(robot.capsules))
    chunks = (int(DT * 1e9) - WORK_NS_TAIL) // (32 * per_sample)  # whole chunks within it
    runs = []
    for _ in range(2):
        method = MPPI(ctx.plan, config, DT, robot)
        obs = observe(robot, 0.0, robot.q0, obstacles=obstacles)
        method.reset(obs)
        commands = [method.step(dataclasses.replace(obs, t=k * DT)) for k in range(3)]
        assert method.status.early_stop and method.status.evaluated == 32 * chunks
        assert method.early_stops == 3
        runs.append(np.concatenate([np.r_[c.q, c.qd] for c in commands]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_a_budget_that_fits_evaluates_every_sample(robot, context):
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig(samples=40, chunk=16, budget=DT)), DT, robot)
    obs = observe(robot, 0.0, robot.q0)
    method.reset(obs)
    method.step(obs)
    assert (method.status.evaluated, method.status.early_stop, method.early_stops) == (40, False, 0)


@pytest.mark.parametrize(
    "change, match",
    [
        ({"budget": 0.02}, r"invalid method.budget=0.02; valid: > 0 and <= the outer period"),
        ({"budget": 0.0}, r"invalid method.budget"),
        ({"samples": 0}, r"invalid method.samples=0; valid: an integer >= 1"),
        ({"chunk": 2.5}, r"invalid method.chunk=2.5"),
        ({"budget_clock": "cpu"}, r"invalid method.budget_clock='cpu'; valid: thread, wall"),
        ({"command": "next"}, r"invalid method.command='next'"),
        ({"knot_dt": 0.004}, r"control_every \* knot_dt = 0.008 s; valid: >= the outer period"),
        ({"temperature": 0.0}, r"invalid method.temperature=0"),
    ],
)
def test_settings_it_cannot_run_with_are_refused_naming_them(robot, context, change, match):
    _, ctx = context
    with pytest.raises(ConfigError, match=match):
        MPPI(ctx.plan, scene(MPPIConfig(**change)), DT, robot)


def test_a_non_finite_observation_is_refused_before_anything_changes(robot, context):
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig()), DT, robot)
    obs = observe(robot, 0.0, robot.q0)
    method.reset(obs)
    method.step(obs)
    controls, steps = method.controls.copy(), method.steps_done
    bad = observe(robot, DT, robot.q0)
    bad.goal[1] = np.nan  # after the observation's own check
    with pytest.raises(InputError, match="non-finite goal"):
        method.step(bad)
    np.testing.assert_array_equal(method.controls, controls)
    assert method.steps_done == steps


# ----------------------------------------------------------------------------- seeding
def _commands(method, robot, n=5, seed_words=None):
    if seed_words is not None:
        method.seed(*seed_words)
    q = robot.q0.copy()
    method.reset(observe(robot, 0.0, q))
    out = []
    for k in range(n):
        command = method.step(observe(robot, k * DT, q))
        q = command.q
        out.append(np.concatenate([command.q, command.qd]))
    return np.array(out)


def test_the_sampler_depends_on_the_seed_and_the_observations_never_on_history(robot, context):
    _, ctx = context
    config = scene(MPPIConfig(samples=64))
    a = MPPI(ctx.plan, config, DT, robot)
    first = _commands(a, robot)
    np.testing.assert_array_equal(_commands(a, robot), first)  # reused: the same episode again
    np.testing.assert_array_equal(_commands(MPPI(ctx.plan, config, DT, robot), robot), first)
    other = MPPI(ctx.plan, dataclasses.replace(config, seed=1), DT, robot)
    assert not np.array_equal(_commands(other, robot), first)
    assert not np.array_equal(_commands(a, robot, seed_words=(0, 3, 7)), first)
    np.random.seed(12345)  # the global generator is never read
    np.testing.assert_array_equal(_commands(a, robot, seed_words=(0,)), first)


BUDGET = "budget_stops"


def _stops(root):
    for path in sorted(root.glob("*/*/episodes.csv")):
        with open(path, newline="") as f:
            yield from ((path, r) for r in csv.DictReader(f))


def _rows(paths):
    rows = []
    for path in paths:
        with open(path, newline="") as f:
            rows += [
                {k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in csv.DictReader(f)
            ]
    return sorted(rows, key=lambda r: int(r["env"]))


@pytest.mark.slow
def test_rows_are_the_same_with_one_worker_and_with_two_shards_on_two_workers(tmp_path):
    """Bit for bit (every column but the timings), Task 4: moving goal and obstacle."""
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    cell = ["task=4", "method=mppi", "episodes=4", "max_time=0.6"]
    for name, extra in (("whole", ["hydra.launcher.n_jobs=1"]), ("split", ["shards=2"])):
        done = subprocess.run(
            [AMEX_RUN, "-m", *cell, *extra, f"hydra.sweep.dir={tmp_path / name}"],
            cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
    whole = _rows((tmp_path / "whole").glob("*/episodes.csv"))
    split = _rows(sorted((tmp_path / "split").glob("*/episodes.csv")))
    assert len(whole) == len(split) == 4 and [r["env"] for r in split] == ["0", "1", "2", "3"]
    assert len({r["final_distance"] for r in whole}) == 4  # four different episodes
    # a step the budget cut short depends on the machine: such an episode is the exception the
    # row declares (budget_stops > 0); every other one is the same bit for bit
    stops = {(p.parent.parent.name, r["env"]) for p, r in _stops(tmp_path) if float(r[BUDGET])}
    same = [a == b for a, b in zip(whole, split, strict=True)]
    for env, equal in enumerate(same):
        declared = ("whole", str(env)) in stops or ("split", str(env)) in stops
        assert equal or declared, f"env {env} differs without a budget stop"
    assert sum(same) >= 2  # not vacuous: most episodes fit their budget at every step


# ----------------------------------------------------------------------------- control
def test_from_a_perturbed_start_on_task_0_it_reaches_the_goal(robot, context):
    config, ctx = context
    rng = np.random.default_rng(3)
    start = robot.q0 + rng.uniform(-0.15, 0.15, robot.nv)
    moved = dataclasses.replace(robot, q0=start)  # the simulated arm starts there
    scenario = make_scenario(config.scene(), 0, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = MPPI(ctx.plan, scene(MPPIConfig()), DT, robot)
    result = run_episode(moved, method, scenario, config.gains(), config.loop)
    assert result.failure == "" and result.success and not result.collided
    assert result.final_distance <= config.loop.stop_radius + 1e-3
    assert result.final_time < 4.0


def test_at_rest_on_the_goal_the_command_holds_still(robot, context):
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig()), DT, robot)
    obs = observe(robot, 0.0, robot.q0, goal=robot.task_position(robot.q0))
    method.reset(obs)
    method.controls[:] = 0.0  # at rest, nothing planned
    command = method.step(obs)
    assert np.abs(command.qd).max() < 1e-3
    assert np.abs(command.q - robot.q0).max() < 1e-4


def test_the_noise_is_drawn_at_the_control_points_and_is_correlated_in_time(robot, context):
    """The sampled accelerations of the intervals are piecewise linear: neighbours correlate."""
    _, ctx = context
    method = MPPI(ctx.plan, scene(MPPIConfig(samples=96, chunk=32, noise=1.0)), DT, robot)
    blocks, costs = [], method.rollouts.costs

    def recorded(q0, v0, controls, noise, *rest):  # the real rollouts, their noise kept
        blocks.append(noise.copy())
        return costs(q0, v0, controls, noise, *rest)

    method.rollouts.costs = recorded
    obs = observe(robot, 0.0, robot.q0)
    method.reset(obs)
    method.step(obs)
    eps = np.concatenate(blocks)
    assert eps.shape == (96, method.B.shape[1], 7) and method.status.evaluated == 96
    assert (eps[0] == 0.0).all()  # sample 0: the warm start itself
    assert (eps[:, 0] == 0.0).all()  # the acceleration being executed is never perturbed
    assert eps[1:, 1:].std() == pytest.approx(1.0, rel=0.05)
    acc = np.einsum("hm,smn->shn", method.B, eps[1:])[:, 2:]  # past the first control interval
    lag1 = np.corrcoef(acc[:, :-1].ravel(), acc[:, 1:].ravel())[0, 1]
    assert lag1 > 0.6  # white noise per interval: 0; linear through the points: 0.6 and 0.9
    steps = np.abs(np.diff(acc, axis=1)).mean() / np.abs(acc).mean()
    assert steps < 0.8  # linear through the points: 0.67; white noise: sqrt(2)


def _episode(robot, context, task, env, config, max_time=None):
    run_config, ctx = context
    scenario = make_scenario(
        run_config.scene(), task, 0, env, ctx.plan.y[0, :3], ctx.plan.duration
    )
    loop = run_config.loop if max_time is None else dataclasses.replace(
        run_config.loop, max_time=max_time
    )
    method = MPPI(ctx.plan, scene(config), DT, robot)
    return method, run_episode(robot, method, scenario, run_config.gains(), loop)


@pytest.mark.parametrize("task, env", [(1, 0), (3, 0), (4, 1)])
def test_short_real_episodes_reach_the_goal_without_collision(robot, context, task, env):
    """Tasks 1, 3 and 4 of the benchmark (seed 0): offset goal, static and moving obstacle."""
    method, result = _episode(robot, context, task, env, MPPIConfig())
    assert result.failure == "" and result.success and not result.collided
    steps = round(result.final_time / DT)
    assert result.budget_stops == pytest.approx(method.early_stops / steps, abs=0.02)
    assert 0.0 <= result.budget_stops <= 1.0


def test_an_episode_on_a_budget_too_short_for_any_chunk_records_every_stop(robot, context):
    """10 us a step: no chunk of 4096 fits, every step sends its warm start; the row says so."""
    config = MPPIConfig(budget=1e-5, samples=4096)
    method, result = _episode(robot, context, 1, 0, config, max_time=0.2)
    assert result.failure == "" and result.budget_stops == 1.0
    assert method.early_stops == method.steps_done > 0
