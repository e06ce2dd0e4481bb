"""The compiled rollout costs of the sampling MPC: every term against numpy and against its meaning.

Real Panda (Pinocchio model, capsules); the numpy reference goes through the batched kinematics'
own numpy paths (``forward``, ``capsule_distances_numpy``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from amex.control.collision import CollisionModel
from amex.plan.batch_kinematics import batch_kinematics
from amex.plan.rollouts import (
    TERMS,
    Rollouts,
    RolloutWeights,
    integrate,
    rollout_costs,
    rollout_costs_numpy,
    rollout_model,
)

DT = 0.05
AXIS = np.array([0.0, 0.0, -1.0])
ALL = RolloutWeights(
    goal_position=300.0,
    goal_axis=10.0,
    final_position=1e4,
    final_axis=400.0,
    final_velocity=10.0,
    velocity=0.1,
    acceleration=0.1,
    collision=100.0,
    collision_margin=0.02,
    limits=100.0,
    limit_margin=0.05,
)
NONE = RolloutWeights(*([0.0] * 8), 0.02, 0.0, 0.05)


@pytest.fixture(scope="module")
def kin(robot):
    return batch_kinematics(robot)


@pytest.fixture(scope="module")
def model(robot, kin):
    return rollout_model(robot, kin, np.sqrt(np.arange(7, 0, -1.0)))


def _tcp(robot, q):
    pose = robot.tcp_pose(q)
    return pose.translation, pose.rotation[:, 2]


def _only(term: str, **extra) -> RolloutWeights:
    names = {
        "position": ("goal_position", "final_position"),
        "axis": ("goal_axis", "final_axis"),
        "velocity": ("velocity", "final_velocity"),
        "acceleration": ("acceleration",),
        "collision": ("collision",),
        "limits": ("limits",),
    }[term]
    return NONE._replace(**{n: getattr(ALL, n) for n in names}, **extra)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("obstacles", [0, 1, 2])
def test_compiled_costs_equal_the_numpy_reference(robot, kin, model, seed, obstacles):
    rng = np.random.default_rng(seed)
    S, H = 9, 7
    q0 = robot.q0 + 0.3 * rng.standard_normal(7)
    v0 = 0.5 * rng.standard_normal(7)
    acc = 2.0 * rng.standard_normal((S, H, 7))
    tcp, z = _tcp(robot, q0)
    centers = tcp - 0.1 * z + 0.03 * rng.standard_normal((obstacles, 3))  # at the hand
    radii = 0.02 + 0.01 * rng.random(obstacles)
    goal = tcp + [0.1, -0.05, 0.02]
    args = (q0, v0, acc, DT, goal, AXIS, centers, radii)
    got = rollout_costs(model, ALL, *args)
    want = rollout_costs_numpy(kin, model, ALL, *args)
    assert got.shape == (S, len(TERMS))
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12)
    if obstacles:
        assert (got[:, TERMS.index("collision")] > 0).any()  # the test exercises the proxy


def test_integration_is_exact_for_held_accelerations(robot):
    rng = np.random.default_rng(4)
    q0, v0, acc = rng.standard_normal(7), rng.standard_normal(7), rng.standard_normal((5, 7))
    q, v = integrate(q0, v0, acc, DT)
    t = DT * np.arange(1, 6)
    for h in range(5):  # piecewise-constant acceleration: sum of the exact parabolas
        vh, qh = v0.copy(), q0.copy()
        for u in acc[: h + 1]:
            qh, vh = qh + DT * vh + 0.5 * DT**2 * u, vh + DT * u
        np.testing.assert_allclose(q[h], qh, atol=1e-14)
        np.testing.assert_allclose(v[h], vh, atol=1e-14)
    np.testing.assert_allclose(integrate(q0, v0, np.zeros((5, 7)), DT)[0], q0 + t[:, None] * v0)


def test_the_velocity_term_is_the_dt_weighted_sum_of_the_integrated_speeds(robot, model):
    rng = np.random.default_rng(5)
    q0, v0, acc = robot.q0, rng.standard_normal(7), rng.standard_normal((3, 6, 7))
    w = _only("velocity")
    terms = rollout_costs(model, w, q0, v0, acc, DT, np.zeros(3), AXIS, np.zeros((0, 3)), [])
    _, v = integrate(q0, v0, acc, DT)
    want = w.velocity * DT * (v**2).sum((1, 2)) + w.final_velocity * (v[:, -1] ** 2).sum(1)
    np.testing.assert_allclose(terms[:, TERMS.index("velocity")], want, rtol=1e-12)
    assert (np.delete(terms, TERMS.index("velocity"), axis=1) == 0).all()


def test_the_acceleration_term_uses_the_metric(robot, model):
    acc = np.zeros((1, 4, 7))
    acc[0, 1, 0] = 2.0  # joint 1, metric sqrt(7)
    w = _only("acceleration")
    terms = rollout_costs(model, w, robot.q0, np.zeros(7), acc, DT, np.zeros(3), AXIS,
                          np.zeros((0, 3)), [])  # fmt: skip
    assert terms[0, TERMS.index("acceleration")] == pytest.approx(0.1 * DT * np.sqrt(7) * 4.0)


def test_the_goal_terms_vanish_at_the_goal_and_grow_away_from_it(robot, model):
    tcp, axis = _tcp(robot, robot.q0)
    still = np.zeros((1, 4, 7))
    for term, goal, goal_axis in (("position", tcp, AXIS), ("axis", tcp + 1.0, axis)):
        w = _only(term)
        at = rollout_costs(model, w, robot.q0, np.zeros(7), still, DT, goal, goal_axis,
                           np.zeros((0, 3)), [])  # fmt: skip
        assert at[0, TERMS.index(term)] == pytest.approx(0.0, abs=1e-20)
    w = _only("position")
    off = np.array([0.03, 0.0, 0.04])  # 5 cm away, for all 4 knots
    terms = rollout_costs(model, w, robot.q0, np.zeros(7), still, DT, tcp + off, AXIS,
                          np.zeros((0, 3)), [])  # fmt: skip
    want = w.goal_position * DT * 4 * 0.05 + w.final_position * 0.05**2  # distance, then squared
    assert terms[0, TERMS.index("position")] == pytest.approx(want, rel=1e-9)


def test_the_collision_proxy_is_zero_beyond_the_margin_and_counts_moving_capsules_only(
    robot, model
):
    """Against coal's distance (the inner controller's collision model), not the kernel's own."""
    q = robot.q0
    still = np.zeros((1, 3, 7))
    w = _only("collision")
    tcp, _ = _tcp(robot, q)
    radii = np.array([0.02])
    coal = CollisionModel(robot, radii)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    for height, active in ((0.30, False), (0.05, True)):
        center = tcp[None] + [[0.0, 0.0, -height]]  # below the tool centre point
        coal.set_obstacles(center)
        d = coal.min_distance(data)
        terms = rollout_costs(model, w, q, np.zeros(7), still, DT, tcp, AXIS, center, radii)
        assert (terms[0, TERMS.index("collision")] > 0) == active == (d < w.collision_margin)
    kin = batch_kinematics(robot)  # the capsule fixed to the base is left out
    assert (kin.cap_joint == 0).sum() == 1 and len(model.cap_joint) == len(kin.cap_joint) - 1


def test_the_limit_term_is_zero_inside_and_counts_joint_and_speed_excursions(robot, model):
    w = _only("limits")
    still = np.zeros((1, 2, 7))
    inside = rollout_costs(model, w, robot.q0, np.zeros(7), still, DT, np.zeros(3), AXIS,
                           np.zeros((0, 3)), [])  # fmt: skip
    assert inside[0, TERMS.index("limits")] == 0.0
    q = robot.q0.copy()
    q[3] = model.upper[3] + 0.1  # joint 4 0.1 rad beyond its upper limit (0.15 inside the margin)
    v = np.zeros(7)
    v[6] = model.speed[6] + 0.2  # joint 7 0.2 rad/s too fast; it moves 0.01 rad per knot
    terms = rollout_costs(model, w, q, v, still, DT, np.zeros(3), AXIS, np.zeros((0, 3)), [])
    want = w.limits * DT * 2 * (0.15**2 + 0.2**2)
    assert terms[0, TERMS.index("limits")] == pytest.approx(want, rel=1e-9)


def test_a_rollouts_object_interpolates_control_points_and_reuses_its_buffers(robot, kin, model):
    rng = np.random.default_rng(6)
    B = rng.random((8, 3))
    controls, noise = rng.standard_normal((3, 7)), rng.standard_normal((5, 3, 7))
    rollouts = Rollouts(model, ALL, B)
    tcp, _ = _tcp(robot, robot.q0)
    scene = (DT, tcp + 0.1, AXIS, tcp[None] + 0.05, np.array([0.03]))
    first = rollouts.costs(robot.q0, np.zeros(7), controls, noise, *scene)
    again = rollouts.costs(robot.q0, np.zeros(7), controls, noise, *scene)
    np.testing.assert_array_equal(first, again)
    acc = np.matmul(B, controls + noise)
    want = rollout_costs_numpy(kin, model, ALL, robot.q0, np.zeros(7), acc, *scene)
    np.testing.assert_allclose(first, want, rtol=1e-10, atol=1e-12)
