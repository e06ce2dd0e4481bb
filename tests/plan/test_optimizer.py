"""Gauss-Newton trajectory optimizer: derivatives, band structure, convergence, errors.

The ``robot`` fixture (the real Panda) comes from ``conftest.py``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from amex.control.collision import CollisionModel
from amex.core.errors import ConfigError, SolverError
from amex.plan.knots import shift_warm_start
from amex.plan.optimizer import (
    TrajectoryCosts,
    TrajectoryProblem,
    batch_kinematics,
    build_normal_equations,
    solve_trajectory,
    solve_trajectory_newton,
    trajectory_residuals,
)
from amex.plan.weights import CollisionWeights

GOAL_POS = np.array([0.384, 0.229, 0.461])  # the Panda's reference goal (scale 0.2) [m]
GOAL_AXIS = np.array([0.0, 0.0, -1.0])
START_TCP = np.array([0.307, 0.0, 0.487])  # TCP at q0 [m]
STEP = 1e-6  # finite-difference step [rad]; revolute joints, so pin.integrate is q + dq
TOL = 1e-5

TERMS = (
    "acceleration",
    "final_position",
    "final_velocity",
    "final_axis",
    "final_axis_velocity",
    "collision",
)


def band_to_dense(band: np.ndarray) -> np.ndarray:
    """Symmetric matrix from LAPACK lower band storage, band[i - j, j] = H[i, j]."""
    n = band.shape[1]
    H = np.zeros((n, n))
    for o in range(min(band.shape[0], n)):
        H[np.arange(o, n), np.arange(n - o)] = band[o, : n - o]
        H[np.arange(n - o), np.arange(o, n)] = band[o, : n - o]
    return H


def random_case(robot, seed: int, costs: TrajectoryCosts, steps: int = 5):
    """A small problem with random knots, start velocity, goal, and obstacles near the arm."""
    rng = np.random.default_rng(seed)
    q = robot.q0 + 0.2 * rng.standard_normal((steps + 1, 7))
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q[steps // 2])
    centers = np.array([data.oMi[j].translation + 0.15 * rng.standard_normal(3) for j in (4, 7)])
    axis = GOAL_AXIS + 0.3 * rng.standard_normal(3)
    problem = TrajectoryProblem(
        q_start=q[0],
        v_start=0.5 * rng.standard_normal(7),
        steps=steps,
        dt=0.05,
        goal_pos=GOAL_POS + 0.1 * rng.standard_normal(3),
        goal_axis=axis / np.linalg.norm(axis),
        obstacles=centers,
        obstacle_radii=np.array([0.05, 0.08]),
        costs=costs,
    )
    return problem, q


def only(term: str) -> TrajectoryCosts:
    weights = {t: 0.0 for t in TERMS}
    weights[term] = getattr(CollisionWeights(), term)
    return TrajectoryCosts(CollisionWeights(**weights, collision_margin=0.15))


def finite_difference(f, q: np.ndarray) -> np.ndarray:
    """Central differences of f over the free knots q[1:], one column per coordinate."""
    columns = []
    for k in range(1, q.shape[0]):
        for i in range(q.shape[1]):
            dq = np.zeros_like(q)
            dq[k, i] = STEP
            columns.append(np.atleast_1d(f(q + dq) - f(q - dq)) / (2 * STEP))
    return np.array(columns).T


def assert_close(actual: np.ndarray, expected: np.ndarray) -> None:
    scale = max(1.0, float(np.max(np.abs(expected))))
    assert np.max(np.abs(actual - expected)) <= TOL * scale


def collision_margin_is_clear(robot, problem, q) -> bool:
    """No pair within 1e-4 m of the margin (the hinge's kink), and at least one pair active."""
    kin = batch_kinematics(robot)
    d = kin.capsule_distances(kin.forward(q[1:]), problem.obstacles, problem.obstacle_radii)
    gap = d.distance - problem.costs.weights.collision_margin
    return bool(np.min(np.abs(gap)) > 1e-4 and np.any(gap < 0))


@pytest.mark.parametrize("term", TERMS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cost_gradient_matches_finite_differences(robot, term, seed):
    problem, q = random_case(robot, seed, only(term))
    gradient = build_normal_equations(robot, problem, q).gradient
    cost = lambda x: build_normal_equations(robot, problem, x).cost  # noqa: E731
    assert_close(gradient, finite_difference(cost, q)[0])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_collision_gradient_matches_finite_differences(robot, seed):
    problem, q = random_case(robot, seed, only("collision"))
    assert collision_margin_is_clear(robot, problem, q)
    eq = build_normal_equations(robot, problem, q)
    J = finite_difference(lambda x: trajectory_residuals(robot, problem, x), q)
    assert_close(eq.gradient, 2 * J.T @ trajectory_residuals(robot, problem, q))
    assert_close(band_to_dense(eq.hessian), 2 * J.T @ J)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_banded_normal_equations_equal_dense_gauss_newton(robot, seed):
    costs = TrajectoryCosts(CollisionWeights(collision_margin=0.15))
    problem, q = random_case(robot, seed, costs)
    assert collision_margin_is_clear(robot, problem, q)
    eq = build_normal_equations(robot, problem, q)
    r = trajectory_residuals(robot, problem, q)
    J = finite_difference(lambda x: trajectory_residuals(robot, problem, x), q)
    assert eq.hessian.shape == (15, 35)
    assert eq.cost == pytest.approx(r @ r, rel=1e-12)
    assert_close(eq.gradient, 2 * J.T @ r)
    assert_close(band_to_dense(eq.hessian), 2 * J.T @ J)


def test_one_step_horizon_has_consistent_normal_equations(robot):
    problem, q = random_case(
        robot, 3, TrajectoryCosts(CollisionWeights(collision_margin=0.15)), steps=1
    )
    eq = build_normal_equations(robot, problem, q)
    r = trajectory_residuals(robot, problem, q)
    J = finite_difference(lambda x: trajectory_residuals(robot, problem, x), q)
    assert_close(eq.gradient, 2 * J.T @ r)
    assert_close(band_to_dense(eq.hessian), 2 * J.T @ J)


@pytest.mark.parametrize("seed", [0, 1])
def test_batched_kinematics_match_pinocchio(robot, seed):
    q = robot.q0 + np.random.default_rng(seed).standard_normal((4, 7))
    poses = batch_kinematics(robot).forward(q)
    data = robot.model.createData()
    for t in range(len(q)):
        pin.computeJointJacobians(robot.model, data, q[t])
        for j in range(1, robot.model.njoints):
            R = poses.rotation[j, :, :, t].T  # rows of the stored array are columns of R
            np.testing.assert_allclose(R, data.oMi[j].rotation, atol=1e-12)
            np.testing.assert_allclose(poses.position[j, :, t], data.oMi[j].translation, atol=1e-12)
            J = pin.getJointJacobian(robot.model, data, j, pin.LOCAL_WORLD_ALIGNED)
            np.testing.assert_allclose(poses.axis[j, :, t], J[3:, j - 1], atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_capsule_distances_match_coal(robot, seed):
    rng = np.random.default_rng(seed)
    q = robot.q0 + 0.3 * rng.standard_normal(7)
    radii = np.array([0.03, 0.1])
    centers = START_TCP + 0.3 * rng.standard_normal((2, 3))
    kin = batch_kinematics(robot)
    dist = kin.capsule_distances(kin.forward(q[None]), centers, radii)
    coal_model = CollisionModel(robot, radii)
    coal_model.set_obstacles(centers)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    proximities = coal_model.proximities(data, margin=10.0)  # obstacle-major, capsule-minor
    C = len(robot.capsules)
    assert len(proximities) == 2 * C
    for k, prox in enumerate(proximities):
        o, c = divmod(k, C)
        assert prox.joint_id == robot.capsules[c].joint_id
        assert dist.distance[c, o, 0] == pytest.approx(prox.distance, abs=1e-9)
        if prox.distance > 0:
            offset = dist.offset[c, o, :, 0]
            normal = offset / np.linalg.norm(offset)
            np.testing.assert_allclose(normal, prox.normal, atol=1e-8)
            witness = centers[o] + offset - robot.capsules[c].radius * normal
            np.testing.assert_allclose(witness, prox.point, atol=1e-8)


def reference_problem(robot, **changes) -> TrajectoryProblem:
    problem = TrajectoryProblem(
        q_start=robot.q0,
        v_start=np.zeros(7),
        steps=400,
        dt=0.01,
        goal_pos=GOAL_POS,
        goal_axis=GOAL_AXIS,
    )
    return dataclasses.replace(problem, **changes)


def test_reference_problem_converges_to_goal_at_rest(robot):
    solution = solve_trajectory(robot, reference_problem(robot))
    assert solution.converged
    y = robot.task_position(solution.q[-1])
    assert np.linalg.norm(y[:3] - GOAL_POS) < 2e-3
    assert y[3:] @ GOAL_AXIS > 1 - 1e-6
    assert np.max(np.abs(solution.q[-1] - solution.q[-2])) / 0.01 < 1e-2
    np.testing.assert_array_equal(solution.q[0], robot.q0)


def test_warm_start_converges_in_fewer_iterations_than_cold(robot):
    first = solve_trajectory(robot, reference_problem(robot, steps=300))
    dt = 0.01
    problem = reference_problem(
        robot, steps=299, q_start=first.q[1], v_start=(first.q[1] - first.q[0]) / dt
    )
    cold = solve_trajectory(robot, problem)
    warm = solve_trajectory(robot, problem, q_init=shift_warm_start(first.q, 299))
    assert warm.converged and cold.converged
    assert warm.iterations < cold.iterations
    assert warm.cost <= cold.cost * (1 + 1e-3)


def min_distance_along(robot, problem, q) -> float:
    model = CollisionModel(robot, problem.obstacle_radii)
    model.set_obstacles(problem.obstacles)
    data = robot.model.createData()
    distances = []
    for qt in q:
        pin.forwardKinematics(robot.model, data, qt)
        distances.append(model.min_distance(data))
    return min(distances)


def test_collision_term_keeps_trajectory_clear_of_obstacle(robot):
    obstacle = np.array([(START_TCP + GOAL_POS) / 2])
    problem = reference_problem(robot, steps=300, obstacles=obstacle, obstacle_radii=[0.02])
    blind = dataclasses.replace(problem, costs=TrajectoryCosts(CollisionWeights(collision=0.0)))
    d_blind = min_distance_along(robot, problem, solve_trajectory(robot, blind).q)
    d_aware = min_distance_along(robot, problem, solve_trajectory(robot, problem).q)
    assert d_blind < 0.0  # the obstacle sits on the obstacle-free path
    assert d_aware > 0.0
    assert d_aware > d_blind


def test_non_finite_start_raises_solver_error(robot):
    with pytest.raises(SolverError, match="non-finite q_start"):
        reference_problem(robot, q_start=np.full(7, np.nan))


def test_non_finite_initial_guess_raises_solver_error(robot):
    problem = reference_problem(robot, steps=10)
    q_init = np.tile(robot.q0, (11, 1))
    q_init[5, 2] = np.inf
    with pytest.raises(SolverError, match="non-finite trajectory cost") as info:
        solve_trajectory(robot, problem, q_init=q_init)
    assert info.value.problem is problem


def test_invalid_solver_settings_raise_config_error(robot):
    with pytest.raises(ConfigError, match="damping > 0"):
        solve_trajectory(robot, reference_problem(robot, steps=10), damping=0.0)


def test_wrong_initial_guess_shape_raises_solver_error(robot):
    with pytest.raises(SolverError, match="shape"):
        solve_trajectory(robot, reference_problem(robot, steps=10), q_init=np.zeros((10, 7)))


def test_shift_warm_start_drops_first_knot_and_pads_with_last():
    q = np.arange(5.0)[:, None] * np.ones((1, 7))
    np.testing.assert_array_equal(shift_warm_start(q, 3)[:, 0], [1, 2, 3, 4])
    np.testing.assert_array_equal(shift_warm_start(q, 5)[:, 0], [1, 2, 3, 4, 4, 4])
    np.testing.assert_array_equal(shift_warm_start(q, 1)[:, 0], [1, 2])


def test_replanning_around_new_obstacle_lowers_cost_and_penetration(robot):
    plan = solve_trajectory(robot, reference_problem(robot, steps=300))
    obstacle = np.array([(START_TCP + GOAL_POS) / 2])
    problem = reference_problem(
        robot,
        steps=299,
        q_start=plan.q[1],
        v_start=(plan.q[1] - plan.q[0]) / 0.01,
        obstacles=obstacle,
        obstacle_radii=[0.02],
    )
    q_init = shift_warm_start(plan.q, 299)
    before = build_normal_equations(robot, problem, q_init).cost
    replanned = solve_trajectory(robot, problem, q_init=q_init, max_iterations=5)
    assert replanned.iterations <= 5
    assert replanned.cost < before
    assert min_distance_along(robot, problem, replanned.q) > min_distance_along(
        robot, problem, q_init
    )


# ------------------------------------------------------------------ the authors' proxy (CR's)
def proxy_costs(**weights) -> TrajectoryCosts:
    values = {t: 0.0 for t in TERMS} | {"collision": 1.0} | weights
    return TrajectoryCosts(
        CollisionWeights(**values, collision_margin=0.15), collision_cost="proxy"
    )


def proxy_kinks_are_clear(robot, problem, q) -> bool:
    """No pair within 1e-4 m of the margin or of contact (the proxy's kinks), one in the margin."""
    kin = batch_kinematics(robot)
    d = kin.capsule_distances(kin.forward(q[1:]), problem.obstacles, problem.obstacle_radii)
    margin = problem.costs.weights.collision_margin
    kinks = np.abs(np.concatenate([d.distance.ravel(), d.distance.ravel() - margin]))
    return bool(kinks.min() > 1e-4 and np.any((d.distance > 0) & (d.distance < margin)))


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_proxy_gradient_and_gauss_newton_match_finite_differences(robot, seed):
    problem, q = random_case(robot, seed, proxy_costs())
    assert proxy_kinks_are_clear(robot, problem, q)
    eq = build_normal_equations(robot, problem, q)
    r = trajectory_residuals(robot, problem, q)
    assert r.shape == (7 * 5 + 3 + 7 + 3 + 3 + 5,)  # one collision residual per knot
    J = finite_difference(lambda x: trajectory_residuals(robot, problem, x), q)
    assert eq.cost == pytest.approx(r @ r, rel=1e-12)
    assert_close(eq.gradient, 2 * J.T @ r)
    assert_close(band_to_dense(eq.hessian), 2 * J.T @ J)
    cost = lambda x: build_normal_equations(robot, problem, x).cost  # noqa: E731
    assert_close(eq.gradient, finite_difference(cost, q)[0])


@pytest.mark.parametrize("seed", [0, 1])
def test_proxy_residual_is_the_authors_sum_per_knot(robot, seed):
    problem, q = random_case(robot, seed, proxy_costs(collision=4.0))
    r_col = trajectory_residuals(robot, problem, q)[-problem.steps :]
    model = CollisionModel(robot, problem.obstacle_radii)
    model.set_obstacles(problem.obstacles)
    data = robot.model.createData()
    margin = 0.15
    for t, qt in enumerate(q[1:]):
        pin.forwardKinematics(robot.model, data, qt)
        total = 0.0
        for prox in model.proximities(data, margin):  # coal, pair by pair
            cap = robot.capsules[prox.shape]
            center = data.oMi[cap.joint_id].act(cap.placement.translation)
            c = np.linalg.norm(center - problem.obstacles[prox.obstacle])
            reach = margin + 1.5 * (
                cap.half_length + cap.radius + problem.obstacle_radii[prox.obstacle]
            )
            total += (1 - max(prox.distance, 0.0) / margin) * (1 - c / reach)
        assert r_col[t] == pytest.approx(2.0 * total, rel=1e-9, abs=1e-12)  # sqrt(4) = 2


def test_proxy_solves_with_both_solvers_and_keeps_the_trajectory_clear(robot):
    obstacle = np.array([(START_TCP + GOAL_POS) / 2])
    weights = CollisionWeights(collision_margin=0.02)
    problem = reference_problem(
        robot, steps=300, obstacles=obstacle, obstacle_radii=[0.02],
        costs=TrajectoryCosts(weights, collision_cost="proxy"),
    )  # fmt: skip
    blind = dataclasses.replace(problem, costs=TrajectoryCosts(CollisionWeights(collision=0.0)))
    d_blind = min_distance_along(robot, problem, solve_trajectory(robot, blind).q)
    ours = solve_trajectory(robot, problem)
    theirs = solve_trajectory_newton(robot, problem)
    assert d_blind < min_distance_along(robot, problem, ours.q)
    assert d_blind < min_distance_along(robot, problem, theirs.q)


def test_an_unknown_collision_cost_is_a_config_error():
    with pytest.raises(ConfigError, match="collision_cost"):
        TrajectoryCosts(collision_cost="cone")
