"""The compiled Gauss-Newton iteration gives the numpy iteration's numbers bit for bit.

CR's results must not depend on which implementation assembled them: the compiled residuals,
right-hand side and damped band (:mod:`amex.plan.optimizer.assembly`) are compared with the numpy
oracle (:mod:`amex.plan.optimizer.numpy_assembly`) on random problems with obstacles, woken guard
pairs and Levenberg terms, and whole solves with both must agree, sign bits included.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from amex.core.errors import SolverError
from amex.plan import optimizer as opt
from amex.plan.knots import (
    resample_knots,
    resample_knots_numpy,
    whole_knot_rows,
    whole_knots,
)
from amex.plan.knots_kernels import midpoint_target
from amex.plan.optimizer.assembly import CompiledAssembly
from amex.plan.optimizer.assembly_kernels import segment_sum, start_residuals, take_step
from amex.plan.optimizer.numpy_assembly import NumpyAssembly, damped_band_numpy
from amex.plan.optimizer.residuals import acceleration_scale, free_knots, residuals
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.plan.weights import CollisionWeights
from tests.plan.problems import problem_near_obstacles


def identical(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return (
        a.shape == b.shape
        and np.array_equal(a, b, equal_nan=True)
        and np.array_equal(np.signbit(a), np.signbit(b))
    )


@pytest.mark.parametrize("length", [*range(1, 40), 127, 128, 129, 130, 200, 300, 1000])
def test_segment_sum_is_numpys_reduceat(length):
    rng = np.random.default_rng(length)
    for _ in range(20):
        values = rng.normal(size=length) * 10.0 ** rng.integers(-8, 8, size=length)
        values[rng.random(length) < 0.2] = -0.0
        expected = np.add.reduceat(values[:, None], [0], axis=0)[0, 0]
        assert identical(segment_sum(values, 0, length), expected)
    assert identical(segment_sum(np.full(length, -0.0), 0, length), -0.0)


@pytest.mark.parametrize("seed", range(12))
def test_compiled_iteration_equals_numpy_iteration(robot, seed):
    rng = np.random.default_rng(seed)
    T = int(rng.choice([1, 2, 3, 12, 80]))
    problem = problem_near_obstacles(robot, rng, T, int(rng.integers(0, 3)), seed % 2 == 0)
    q = robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv))
    x = free_knots(robot, problem, q)
    fast, slow = CompiledAssembly(robot).begin(problem), NumpyAssembly(robot).begin(problem)
    a, b = fast.evaluate(x), slow.evaluate(x)
    assert a.cost == b.cost
    assert identical(a.r_acc, b.residuals[0]) and identical(a.r_fin, b.residuals[1])
    assert identical(a.J_fin, b.final_jacobian)
    if b.near is not None:
        assert [p.tolist() for p in (a.cap, a.obs, a.knot)] == [p.tolist() for p in b.near]
        assert identical(a.r_near, b.residuals[2][b.near])
    fast_model, slow_model = fast.linearize(a), slow.linearize(b)
    for lam in (0.0, 1e-3, 10.0):
        woken = fast.woken()
        woken[rng.random(woken.shape) < 0.5] = True  # guard pairs woken at random
        band, rhs = fast.system(a, fast_model, woken, lam)
        assert identical(band, damped_band_numpy(slow_model, woken, lam))
        assert identical(rhs, -slow_model.equations.gradient)
        if lam == 0.0:
            band = fast.system(a, fast_model, slow.woken(), 0.0)[0]
            assert identical(band, slow_model.equations.hessian)


def test_the_iteration_tests_cover_guards_and_wakes(robot):
    """The random problems above bring active, inactive and woken pairs (else they test less)."""
    counts = {"active": 0, "inactive": 0, "guarded": 0}
    for seed in range(12):
        rng = np.random.default_rng(seed)
        T = int(rng.choice([1, 2, 3, 12, 80]))
        problem = problem_near_obstacles(robot, rng, T, int(rng.integers(0, 3)), seed % 2 == 0)
        x = free_knots(robot, problem, robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv)))
        point = CompiledAssembly(robot).begin(problem).evaluate(x)
        counts["active"] += int((point.r_near > 0.0).sum())
        counts["inactive"] += int((point.r_near == 0.0).sum())
    counts["guarded"] = counts["inactive"]  # inactive pairs are the guard's, woken at random
    assert min(counts.values()) > 0, counts


@pytest.mark.parametrize("seed", range(16))
def test_compiled_solve_equals_numpy_solve(robot, seed):
    rng = np.random.default_rng(100 + seed)
    T = int(rng.choice([1, 2, 3, 10, 60]))
    problem = problem_near_obstacles(robot, rng, T, int(rng.integers(0, 3)), seed % 2 == 0)
    q_init = robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv))
    a = opt.solve_trajectory(robot, problem, q_init=q_init, max_iterations=8)
    b = opt.solve_trajectory(
        robot, problem, q_init=q_init, max_iterations=8, assembly=NumpyAssembly(robot)
    )
    assert identical(a.q, b.q) and a.cost == b.cost
    assert (a.iterations, a.converged) == (b.iterations, b.converged)
    if b.frames is not None:
        assert identical(a.frames.dist.distance, b.frames.dist.distance)


def problem_through_obstacle(robot, seed: int) -> TrajectoryProblem:
    """A cold solve to a goal behind a sphere: rejected steps wake guard pairs."""
    rng = np.random.default_rng(seed)
    tcp = robot.tcp_pose(robot.q0).translation
    T = int(rng.choice([10, 30, 60]))
    goal = tcp + rng.normal(scale=0.3, size=3)
    obstacles = (0.5 * (tcp + goal) + rng.normal(scale=0.05, size=3))[None]
    weights = CollisionWeights(collision=10.0, collision_margin=0.08)
    return TrajectoryProblem(
        q_start=robot.q0,
        v_start=np.zeros(robot.nv),
        steps=T,
        dt=0.01,
        goal_pos=goal,
        goal_axis=np.array([0.0, 0.0, -1.0]),
        obstacles=obstacles,
        obstacle_radii=np.array([0.05]),
        costs=TrajectoryCosts(weights, tuple(rng.uniform(0.5, 2.0, robot.nv))),
    )


@pytest.mark.parametrize("seed", [0, 4, 7, 13, 15, 18])
def test_compiled_solve_equals_numpy_solve_where_steps_wake_pairs(robot, seed, monkeypatch):
    import amex.plan.optimizer.numpy_assembly as numpy_assembly

    woke = []
    wake = numpy_assembly.wake_pushed_in

    def counted(*args):
        woke.append(wake(*args))
        return woke[-1]

    monkeypatch.setattr(numpy_assembly, "wake_pushed_in", counted)
    problem = problem_through_obstacle(robot, seed)
    a = opt.solve_trajectory(robot, problem)
    b = opt.solve_trajectory(robot, problem, assembly=NumpyAssembly(robot))
    assert any(woke)  # the case this test is for
    assert identical(a.q, b.q) and a.cost == b.cost
    assert (a.iterations, a.converged) == (b.iterations, b.converged)


@pytest.mark.parametrize("seed", range(8))
def test_newton_on_the_compiled_iteration_equals_newton_on_numpy(robot, seed):
    """The authors' solver and TCP final velocity, without the proxy term in play (no
    obstacles, or the hinge term in its place)."""
    rng = np.random.default_rng(200 + seed)
    T, k = int(rng.choice([1, 2, 10, 60])), seed % 3
    problem = problem_near_obstacles(robot, rng, T, k, True)
    form = "hinge" if k else "proxy"
    costs = TrajectoryCosts(problem.costs.weights, problem.costs.metric, "tcp", form)
    problem = dataclasses.replace(problem, costs=costs)
    q_init = robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv))
    a = opt.solve_trajectory_newton(robot, problem, q_init)
    b = opt.solve_trajectory_newton(robot, problem, q_init, assembly=NumpyAssembly(robot))
    assert identical(a.q, b.q) and a.cost == b.cost
    assert (a.iterations, a.converged) == (b.iterations, b.converged)
    c = opt.solve_trajectory(robot, problem, q_init=q_init)  # and ours with these costs
    d = opt.solve_trajectory(robot, problem, q_init=q_init, assembly=NumpyAssembly(robot))
    assert identical(c.q, d.q) and c.cost == d.cost


def test_a_reused_assembly_gives_the_same_solutions(robot):
    """CR keeps one assembly (buffers, Pinocchio data) from step to step: no state leaks."""
    rng = np.random.default_rng(5)
    assembly = CompiledAssembly(robot)
    for T in (60, 59, 80, 3, 1, 40):
        problem = problem_near_obstacles(robot, rng, T, 1, True)
        q_init = robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv))
        kept = opt.solve_trajectory(robot, problem, q_init=q_init, assembly=assembly)
        fresh = opt.solve_trajectory(robot, problem, q_init=q_init)
        assert identical(kept.q, fresh.q) and kept.cost == fresh.cost


def test_take_step_tells_small_steps_as_max_abs_does():
    rng = np.random.default_rng(2)
    x, q0, v0, scale = rng.normal(size=(5, 7)), rng.normal(size=7), rng.normal(size=7), np.ones(7)
    for step in (rng.normal(scale=1e-4, size=35), rng.normal(scale=1e-2, size=35)):
        for bad in (None, np.nan):
            if bad is not None:
                step = step.copy()
                step[7] = bad
            out, r_acc, v_last = np.empty_like(x), np.empty_like(x), np.empty(7)
            small = take_step(x, step, q0, v0, 0.01, scale, 1e-3, out, r_acc, v_last)
            assert small == (float(np.max(np.abs(step))) < 1e-3)
            assert identical(out, x + step.reshape(x.shape))
            assert identical(v_last, (out[-1] - out[-2]) / 0.01)


def test_compiled_resampling_equals_numpy():
    rng = np.random.default_rng(1)
    for _ in range(500):
        knots = rng.normal(size=(int(rng.integers(1, 30)), 7))
        offset = float(rng.choice([0.0, 0.5, rng.uniform(-2.0, len(knots) + 2.0), 1.0 + 1e-10]))
        stride = float(rng.choice([0.0, 0.5, 1.0, 1.5, rng.uniform(0.0, 3.0)]))
        count = int(rng.integers(1, 40))
        fast = resample_knots(knots, offset, stride, count)
        assert identical(fast, resample_knots_numpy(knots, offset, stride, count))


def test_whole_knot_rows_are_whole_knots():
    for length in range(1, 12):
        for offset in np.arange(-3.0, 14.0, 0.5):
            for stride in (0.0, 0.5, 1.0, 2.0):
                for count in range(1, 16):
                    rows = whole_knot_rows(length, offset, stride, count)
                    index = whole_knots(length, offset, stride, count)
                    assert (rows is None) == (index is None)
                    if index is not None:
                        assert np.arange(length)[rows].tolist() == index.tolist()


def test_start_residuals_are_the_numpy_residuals_and_final_velocity(robot):
    """The first iterate's kernel gives :func:`~.residuals.residuals`' r_acc and final_terms' v."""
    rng = np.random.default_rng(3)
    for T in (1, 2, 3, 40):
        problem = problem_near_obstacles(robot, rng, T, 0, T % 2 == 0)
        x = free_knots(robot, problem, robot.q0 + rng.normal(scale=0.3, size=(T + 1, robot.nv)))
        s_acc = acceleration_scale(problem.costs, problem.dt)
        scale = np.full(robot.nv, s_acc) if isinstance(s_acc, float) else s_acc
        r_acc, v_last = np.empty_like(x), np.empty(robot.nv)
        start_residuals(x, problem.q_start, problem.v_start, problem.dt, scale, r_acc, v_last)
        point = residuals(robot, robot.model.createData(), problem, x)
        assert identical(r_acc, point.residuals[0])
        q_prev = x[-2] if T > 1 else problem.q_start
        assert identical(v_last, (x[-1] - q_prev) / problem.dt)


def test_compiled_midpoint_target_equals_the_numpy_target():
    """CR's target kernel: the blended rows of resample_knots and (q2 - q0) / dt, bit for bit."""
    rng = np.random.default_rng(4)
    for _ in range(500):
        knots = rng.normal(size=(int(rng.integers(2, 30)), 7))
        stride = float(rng.choice([0.5, 0.25, 1.5, rng.uniform(0.0, 3.0)]))
        dt = float(rng.choice([0.01, 0.001, rng.uniform(1e-3, 0.1)]))
        if whole_knots(len(knots), 0.0, stride, 3) is not None:
            continue
        q = resample_knots_numpy(knots, 0.0, stride, 3)
        q_mid, qd = np.empty(7), np.empty(7)
        midpoint_target(knots, stride, dt, q_mid, qd)
        assert identical(q_mid, q[1]) and identical(qd, (q[2] - q[0]) / dt)


def test_problem_checks_what_it_checked():
    """TrajectoryProblem's own __init__: copies, the default obstacles, the same errors."""
    q, g = np.zeros(7), np.array([0.0, 0.0, 1.0])
    p = TrajectoryProblem(q, q, 3, 0.01, g, g)
    assert p.obstacles.shape == (0, 3) and p.obstacle_radii.shape == (0,) and p.q_start is not q
    assert dataclasses.replace(p, steps=4).steps == 4
    bad = [
        dict(v_start=np.zeros(6)),
        dict(goal_pos=np.zeros(2)),
        dict(obstacles=np.zeros((1, 3))),
        dict(q_start=np.full(7, np.nan)),
        dict(steps=0),
        dict(steps=1.5),
        dict(dt=0.0),
        dict(dt=math.inf),
    ]
    for change in bad:
        with pytest.raises(SolverError, match="trajectory problem"):
            dataclasses.replace(p, **change)
