"""The compiled Levenberg loop solves as the Python loop does, its kinematics as Pinocchio's.

:mod:`amex.plan.optimizer.compiled_loop` runs :func:`~amex.plan.optimizer.solve_trajectory`'s
iterations in one compiled call, with the final terms' TCP kinematics of its own (Pinocchio cannot
be called there). The kinematics agree with Pinocchio's to rounding; solves take the same
iterations to the same stop and agree to rounding amplified by a few iterations; failures raise
the Python loop's errors.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from amex.core.errors import SolverError
from amex.plan import optimizer as opt
from amex.plan.optimizer import blas, compiled_loop
from amex.plan.optimizer.assembly import CompiledAssembly
from amex.plan.optimizer.compiled_loop import tcp_kinematics
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.plan.weights import CollisionWeights
from amex.robot import load_robot
from tests.plan.problems import problem_near_obstacles

pytestmark = pytest.mark.skipif(not blas.BOUND, reason="numpy is not built on its OpenBLAS")


@pytest.mark.parametrize("name", ["panda", "ur5", "chain7"])
def test_tcp_kinematics_are_pinocchios(name):
    robot = load_robot(name)
    model, data, fid = robot.model, robot.model.createData(), robot.tcp_frame_id
    arrays = CompiledAssembly(robot).compiled_robot
    rng = np.random.default_rng(3)
    n = model.nv
    for _ in range(50):
        q = rng.uniform(-3.0, 3.0, n)
        pin.computeJointJacobians(model, data, q)
        placement = pin.updateFramePlacement(model, data, fid)
        J_pin = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        J, R, p = np.empty((6, n)), np.empty((3, 3)), np.empty(3)
        tcp_kinematics(*arrays[:2], q, *arrays[2:6], J, R, p)
        assert np.allclose(J, J_pin, rtol=0, atol=1e-14)
        assert np.allclose(R, placement.rotation, rtol=0, atol=1e-14)
        assert np.allclose(p, placement.translation, rtol=0, atol=1e-14)
        assert not np.array_equal(J, np.zeros_like(J))


def both_loops(robot, problem, monkeypatch, **kwargs):
    compiled = opt.solve_trajectory(robot, problem, compiled=True, **kwargs)
    with monkeypatch.context() as m:
        m.setattr(compiled_loop, "ENABLED", False)
        python = opt.solve_trajectory(robot, problem, **kwargs)
    return compiled, python


@pytest.mark.parametrize("seed", range(24))
def test_the_compiled_loop_solves_as_the_python_loop(robot, seed, monkeypatch):
    rng = np.random.default_rng(300 + seed)
    T, k = int(rng.choice([2, 3, 10, 60, 200])), int(rng.integers(0, 3))
    problem = problem_near_obstacles(robot, rng, T, k, seed % 2 == 0)
    q_init = robot.q0 + rng.normal(scale=0.1, size=(T + 1, robot.nv))
    a, b = both_loops(robot, problem, monkeypatch, q_init=q_init, max_iterations=8)
    assert (a.iterations, a.converged) == (b.iterations, b.converged)
    # a solve stopped by the cap, far from its minimum, amplifies the last bits most (~3e-9)
    tol = 1e-10 if b.converged else 1e-7
    assert np.allclose(a.q, b.q, rtol=0, atol=tol) and abs(a.cost - b.cost) <= tol * b.cost
    assert np.array_equal(a.q[0], problem.q_start)
    assert (a.frames is None) == (b.frames is None) == (k == 0)
    if a.frames is not None:
        assert a.frames.poses.position.shape == b.frames.poses.position.shape
        assert np.allclose(a.frames.dist.distance, b.frames.dist.distance, rtol=0, atol=tol)


@pytest.mark.parametrize("seed", [0, 4, 7, 13])
def test_the_compiled_loop_wakes_pairs_as_the_python_loop(robot, seed, monkeypatch):
    """A cold solve to a goal behind a sphere: rejected steps wake guard pairs."""
    rng = np.random.default_rng(seed)
    tcp = robot.tcp_pose(robot.q0).translation
    goal = tcp + rng.normal(scale=0.3, size=3)
    problem = TrajectoryProblem(
        q_start=robot.q0,
        v_start=np.zeros(robot.nv),
        steps=int(rng.choice([10, 30, 60])),
        dt=0.01,
        goal_pos=goal,
        goal_axis=np.array([0.0, 0.0, -1.0]),
        obstacles=(0.5 * (tcp + goal) + rng.normal(scale=0.05, size=3))[None],
        obstacle_radii=np.array([0.05]),
        costs=TrajectoryCosts(CollisionWeights(collision=10.0, collision_margin=0.08)),
    )
    a, b = both_loops(robot, problem, monkeypatch)
    assert (a.iterations, a.converged) == (b.iterations, b.converged)
    assert np.allclose(a.q, b.q, rtol=0, atol=1e-8)


def test_warm_started_frames_are_used_as_the_python_loop_uses_them(robot, monkeypatch):
    """CR's step: the last solution's frames, shifted by a knot, for the same obstacles."""
    rng = np.random.default_rng(11)
    problem = problem_near_obstacles(robot, rng, 60, 2, True)
    first = opt.solve_trajectory(robot, problem, q_init=np.tile(robot.q0, (61, 1)), compiled=True)
    frames = first.frames.take(slice(1, 60))
    shifted = TrajectoryProblem(
        first.q[1], problem.v_start, 59, 0.01, problem.goal_pos, problem.goal_axis,
        problem.obstacles, problem.obstacle_radii, problem.costs,
    )  # fmt: skip
    a, b = both_loops(robot, shifted, monkeypatch, q_init=first.q[1:], init_frames=frames)
    assert (a.iterations, a.converged) == (b.iterations, b.converged)
    assert np.allclose(a.q, b.q, rtol=0, atol=1e-9)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_failures_raise_the_python_loops_errors(robot, monkeypatch):
    rng = np.random.default_rng(2)
    problem = problem_near_obstacles(robot, rng, 10, 1, False)
    q_init = np.tile(robot.q0, (11, 1))
    q_init[5, 2] = np.inf  # a non-finite initial guess: its cost
    for enabled in (True, False):
        monkeypatch.setattr(compiled_loop, "ENABLED", enabled)
        with pytest.raises(SolverError, match="non-finite trajectory cost .* initial guess"):
            opt.solve_trajectory(robot, problem, q_init=q_init, compiled=True)
    bad = TrajectoryProblem.prechecked(
        problem.q_start.copy(), problem.v_start, 10, 0.01, problem.goal_pos,
        problem.goal_axis, problem.obstacles, problem.obstacle_radii, problem.costs,
    )  # fmt: skip
    bad.q_start[1] = np.nan  # a prechecked input that is not finite after all: named
    for enabled in (True, False):
        monkeypatch.setattr(compiled_loop, "ENABLED", enabled)
        with pytest.raises(SolverError, match="non-finite q_start"):
            opt.solve_trajectory(robot, bad, q_init=np.tile(robot.q0, (11, 1)), compiled=True)
