"""The authors' implementations (implementation=original) and the original experiment's config."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from amex.app.compose import load_config
from amex.experiment.runner import prepare, run_one
from amex.methods import CR, AMEXOriginal, CROriginal, DMPOriginal, get_method
from amex.methods.base import Observation
from amex.methods.cr import CRConfig
from amex.methods.original.amex import PiecewiseLinearPlan
from amex.plan.optimizer import TrajectoryProblem, solve_trajectory, solve_trajectory_newton
from amex.plan.reference import ReferencePlan
from amex.sim.loop import authors_samples
from amex.sim.scenario import goal_grid, plan_goal, with_reference_goal

T_REF, DT = 4.0, 0.01


def _reference(n=401):
    s = np.linspace(0.0, 1.0, n)[:, None]
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5  # rest to rest
    start = np.array([0.36, -2.55, 1.83, 0.07, -1.0, 0.07])
    goal = np.array([0.75, -1.40, 1.70, 1.0, 0.0, 0.0])
    return start + blend * (goal - start)


def _plan() -> ReferencePlan:
    return ReferencePlan.from_path(_reference(), T_REF)  # samples DT apart


@pytest.fixture(scope="module")
def original():
    config = load_config(["experiment=original", "task=1", "method=cr", "episodes=2"])
    return config, prepare(config)


def test_the_linear_plan_interpolates_and_its_warp_keeps_the_invariants():
    rng = np.random.default_rng(0)
    Y = _reference()
    plan = PiecewiseLinearPlan(Y)
    s = rng.uniform(0, 1, 20)
    expected = np.stack([np.interp(s, plan.knots, Y[:, j]) for j in range(6)], axis=1)
    np.testing.assert_allclose([plan.value(x) for x in s], expected, atol=1e-12)
    np.testing.assert_array_equal(plan.value(1.3), Y[-1])
    y, g_shift = Y[123] + 0.05, np.r_[0.1, -0.2, 0.05, 0.0, 0.0, 0.0]
    s0 = 0.31
    plan.warp(g_shift, y - plan.value(s0), s0)
    np.testing.assert_allclose(plan.value(s0), y, atol=1e-12)  # Eq. 7: the plan passes y at s
    np.testing.assert_allclose(plan.value(1.0), Y[-1] + g_shift, atol=1e-12)  # and ends at g


def test_original_amex_steps_the_phase_twice_by_the_reference_rate_then_by_eq8():
    amex = AMEXOriginal(_plan(), None, DT)
    y, g = _reference()[0], _reference()[-1]
    for expected in (DT / T_REF, 2 * DT / T_REF):
        target = amex.update(y, g)
        assert amex.s == pytest.approx(expected) and target.delta_g == target.delta_y == 1.0
        y = target.y_star  # perfect execution
    target = amex.update(y, g)
    assert target.delta_y == pytest.approx(1.0) and target.delta_g != 1.0  # Eq. 8 from now on


def test_original_amex_divides_by_zero_like_the_original():
    amex = AMEXOriginal(_plan(), None, DT)
    y = _reference()[0]
    for _ in range(3):
        target = amex.update(y, _reference()[-1])  # the robot never moves: delta_y = 0 / step
    assert target.delta_y == 0.0 and amex.s == pytest.approx(2 * DT / T_REF)


def test_original_dmp_runs_its_motion_in_8_seconds_of_time_constant():
    dmp = DMPOriginal(_plan(), None, DT)
    assert 1.0 / dmp.tau == pytest.approx(8.02)
    ys = np.array([dmp.update(_reference()[-1]).y_star for _ in range(400)])
    assert np.abs(ys - _reference()[1:]).max() < 0.02  # the reference, at its own pace
    assert np.abs(ys[-1] - _reference()[-1]).max() < 0.01


def _arrival(update) -> float:
    """When the DMP comes within 3 cm of a goal that moves for 2.8 s (Task 2) [s]."""
    g0, v = _reference()[-1], np.r_[0.1, -0.1, 0.05, 0.0, 0.0, 0.0]
    for k in range(1000):
        g = g0 + v * min(k * DT, 2.8)
        y = update(g)
        if k * DT > 2.8 and np.linalg.norm(y[:3] - g[:3]) < 0.03:
            return k * DT
    return np.inf


def test_original_dmp_follows_a_moving_goal_a_second_later():
    ours = get_method("dmp")(_plan(), None, DT)
    theirs = DMPOriginal(_plan(), None, DT)
    late = _arrival(lambda g: theirs.update(g).y_star) - _arrival(
        lambda g: ours.update(g, DT).y_star
    )
    assert late > 0.8  # time constant 8.02 s against 4 s


def test_newton_stops_without_an_update_at_an_optimum_and_agrees_with_levenberg(original):
    config, ctx = original
    robot, plan = ctx.robot, ctx.plan
    goal = plan_goal(config.scene(), 1, plan.y[0, :3])
    problem = TrajectoryProblem(
        robot.q0, np.zeros(7), 400, 0.01, goal, np.array(config.scenario.goal_axis),
        costs=CROriginal(plan, config.method_config(), 0.01, robot).costs,
    )  # fmt: skip
    levenberg = solve_trajectory(robot, problem, q_init=plan.q, tolerance=1e-9, max_iterations=50)
    newton = solve_trajectory_newton(robot, problem, q_init=levenberg.q)
    assert newton.converged and newton.iterations == 1
    np.testing.assert_array_equal(newton.q, levenberg.q)  # the lazy stop: nothing changed


def test_original_cr_shrinks_its_horizon_and_ends_the_episode_at_t_ref(original):
    config, ctx = original
    cr = CROriginal(ctx.plan, config.method_config(), 0.01, ctx.robot)
    goal = np.r_[ctx.plan.y[-1, :3], config.scenario.goal_axis]
    q, steps = ctx.plan.q, []
    for k in range(400):
        obs = Observation(k * 0.01, q[min(k, 400)], np.zeros(7), ctx.plan.y[0], np.zeros(6), goal)
        command = cr.step(obs)
        steps.append(len(cr.knots))
        if cr.finished:
            break
    assert k == 399 and steps[0] == 400 and steps[-2] == 3  # one knot less per step
    assert command.q is not None and np.isfinite(command.qd).all()


def test_the_original_experiment_composes_the_authors_setup():
    config = load_config(["experiment=original", "task=3"])
    assert (config.robot.name, config.scenario.scale, config.sim) == ("chain7", 1.0, "kinematic")
    assert config.implementation == "original" and config.state_lag
    assert config.scenario.plane_grid == [10, 15]
    scene = with_reference_goal(config.scene(), np.zeros(3))
    np.testing.assert_allclose(plan_goal(scene, 3, np.zeros(3)), [1.1, -1.4, 1.7])
    np.testing.assert_allclose(plan_goal(scene, 1, np.zeros(3)), [0.75, -1.4, 1.7])
    box = goal_grid(scene, 1)
    np.testing.assert_allclose(box.min(axis=0), [0.4, -1.8, 0.8])
    np.testing.assert_allclose(box.max(axis=0), [1.1, -1.0, 2.6])
    assert config.loop.stop_radius == 0.03
    assert config.loop.final_time == "samples" and config.std_ddof == 1  # their MATLAB std
    controller = config.controller
    assert (controller.collision_cost, controller.col.weight) == ("proxy", 1.0)
    assert controller.proxy_arm_radii == [0.3] * 6 + [0.0002]
    assert config.gains().proxy_obstacle_radius == 0.1


def test_original_cr_plans_with_their_proxy_and_ours_with_the_hinge(original):
    config, ctx = original
    params = config.method_config()
    assert CROriginal(ctx.plan, params, 0.01, ctx.robot).costs.collision_cost == "proxy"
    assert CR(ctx.plan, params, 0.01, ctx.robot).costs.collision_cost == "hinge"
    hinge = CRConfig(**{**vars(params), "collision_cost": "hinge"})
    assert CROriginal(ctx.plan, hinge, 0.01, ctx.robot).costs.collision_cost == "hinge"
    with pytest.raises(Exception, match="collision_cost"):
        CROriginal(ctx.plan, CRConfig(collision_cost="cone"), 0.01, ctx.robot)


def test_their_final_time_counts_the_samples_their_harness_wrote():
    assert authors_samples(3630, False, False, 10.0, 1e-3) == 3631  # goal reached at 3.63 s
    assert authors_samples(3990, False, True, 10.0, 1e-3) == 3992  # their CR's end: 3.992 s
    assert authors_samples(10000, True, False, 10.0, 1e-3) == 10002  # t += dt reaches 10 late


@pytest.mark.parametrize("method", ["amex", "dmp", "cr"])
def test_an_original_episode_reaches_a_task1_goal(method):
    config = load_config(["experiment=original", "task=1", f"method={method}", "episodes=1"])
    result = run_one(config, prepare(config), 0)
    assert result.success and not result.failure, result
    assert result.sum_sq_acc_paper > result.sum_sq_acc  # rounding noise on top
    elapsed = run_one(replace(config, final_time="elapsed"), prepare(config), 0).final_time
    assert result.final_time == pytest.approx(elapsed + 1e-3, abs=1e-9)  # one sample more


def test_the_ablation_switches_the_authors_metrics_then_their_collision_task():
    steps = {
        s: load_config([f"experiment=ablation/{s}", "task=3", "method=cr"])
        for s in ("1_harness", "2_controller", "3_methods")
    }
    harness, controller, methods = steps.values()
    assert (harness.final_time, harness.std_ddof) == ("elapsed", 0)
    assert harness.controller.collision_cost == "proxy" and harness.controller.col.weight == 1.0
    assert controller.controller.collision_cost == "hinge"
    assert controller.controller.col.weight == 10.0
    assert controller.implementation == "original" and methods.implementation == "ours"
    # CR's plan term is its implementation's own (auto): theirs until step 3 replaces it
    assert {s.method_config().collision_cost for s in steps.values()} == {"auto"}
