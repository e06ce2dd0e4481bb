"""The compiled collision tasks against their numpy oracles; coal's results read without copies."""

from __future__ import annotations

import numpy as np
import pytest

from amex.control.collision import TABLE_COLUMNS, CollisionModel
from amex.control.state import RobotState
from amex.control.tasks import CollisionMap, ProxyMap
from amex.robot import RobotConfig, load_robot

#: (margin [m], obstacle radius [m]) per robot: the Panda at scale 0.2, the authors' chain at 1.
ROBOTS = {"panda": (0.02, 0.02), "chain7": (0.1, 0.1)}


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def arm(request):
    return request.param, load_robot(RobotConfig(name=request.param))


def _state(robot, q, rng):
    return RobotState(robot, robot.model.createData(), q, rng.normal(size=robot.nv))


def _near_tcp(robot, q, offset, radius, n=1):
    """A collision model with ``n`` obstacles about ``offset`` [m] from the TCP."""
    collision = CollisionModel(robot, [radius] * n)
    tcp = robot.tcp_pose(q).translation
    centers = tcp + offset * np.array([[0.0, 0.0, -1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])[:n]
    collision.set_obstacles(centers)
    return collision


def _accessor_table(collision):
    """What coal's and Pinocchio's own accessors say (the views must hold exactly this)."""
    rows = []
    for res in collision.geom_data.distanceResults:
        rows.append([res.min_distance, *res.normal, *res.getNearestPoint1(),
                     *res.getNearestPoint2()])  # fmt: skip
    placements = [
        [*oMg.rotation.ravel(order="F"), *oMg.translation] for oMg in collision.geom_data.oMg
    ]
    return np.array(rows), np.array(placements)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_views_hold_exactly_what_coal_and_pinocchio_report(arm, seed):
    _, robot = arm
    rng = np.random.default_rng(seed)
    q = robot.q0 + rng.normal(scale=0.3, size=robot.nv)
    collision = _near_tcp(robot, q, 0.05, 0.02, n=2)
    assert collision.zero_copy  # these libraries' layout is the one the views expect
    assert collision.table.shape == (2 * len(robot.capsules), len(TABLE_COLUMNS))
    d = collision.update(_state(robot, q, rng).data)
    table, placements = _accessor_table(collision)
    np.testing.assert_array_equal(collision.table, table)
    np.testing.assert_array_equal(collision.placements, placements)
    assert d == table[:, 0].min()


def test_the_copying_fallback_reads_the_same_numbers(robot):
    rng = np.random.default_rng(4)
    q = robot.q0 + rng.normal(scale=0.3, size=7)
    fast, slow = (_near_tcp(robot, q, 0.03, 0.02) for _ in range(2))
    slow.zero_copy = False  # as when a library's memory layout is not the expected one
    slow.table, slow.placements = np.zeros_like(slow.table), np.zeros_like(slow.placements)
    state = _state(robot, q, rng)
    assert fast.update(state.data) == slow.update(state.data)
    np.testing.assert_array_equal(fast.table, slow.table)
    np.testing.assert_array_equal(fast.placements, slow.placements)


def test_a_second_update_for_the_same_state_is_not_computed_again(robot):
    rng = np.random.default_rng(5)
    q = robot.q0.copy()
    collision = _near_tcp(robot, q, 0.03, 0.02)
    state = _state(robot, q, rng)
    d = collision.update(state.data, state)
    collision.geom_data.distanceResults[0].min_distance = -1.0  # changes only if recomputed
    assert collision.update(state.data, state) == d
    collision.set_obstacles(collision.centers + 0.5)  # moved: computed again
    assert collision.update(state.data, state) != d


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("offset", [0.0, 0.01, 0.03], ids=["penetrating", "near", "edge"])
def test_compiled_hinge_equals_the_numpy_task_map(arm, seed, offset):
    name, robot = arm
    margin, radius = ROBOTS[name]
    rng = np.random.default_rng(seed)
    q = robot.q0 + rng.normal(scale=0.2, size=robot.nv)
    collision = _near_tcp(robot, q, offset * margin / 0.02 + radius, radius, n=2)
    task = CollisionMap(collision, margin)
    state = _state(robot, q, rng)
    oracle = task.evaluate(state)
    out = np.full(1 + robot.nv, np.nan)
    active = task.terms_into(state, out)
    assert active == bool(collision.proximities(state.data, margin))
    if not active:
        assert out[0] == 0.0 and oracle.phi[0] == 0.0
        return
    assert out[0] == oracle.phi[0]  # the same sum, in the same order
    np.testing.assert_allclose(out[1:], oracle.J[0], rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("offset", [0.0, 0.5], ids=["penetrating", "in_margin"])
def test_compiled_proxy_equals_the_numpy_task_map(arm, seed, offset):
    name, robot = arm
    margin, radius = ROBOTS[name]
    rng = np.random.default_rng(seed)
    q = robot.q0 + rng.normal(scale=0.2, size=robot.nv)
    collision = _near_tcp(robot, q, offset * margin + radius, radius, n=2)
    task = ProxyMap(collision, margin, obstacle_radius=radius)
    state = _state(robot, q, rng)
    oracle = task.evaluate(state)
    out = np.full(1 + robot.nv, np.nan)
    assert task.terms_into(state, out)
    np.testing.assert_allclose(out[0], oracle.phi[0], rtol=1e-14)
    np.testing.assert_allclose(out[1:], oracle.J[0], rtol=1e-12, atol=1e-13)
    assert np.any(out[1:] != 0.0)


def test_out_of_the_margin_the_task_is_off(robot):
    rng = np.random.default_rng(6)
    collision = _near_tcp(robot, robot.q0, 0.5, 0.02)
    out = np.full(8, np.nan)
    assert not CollisionMap(collision, 0.02).terms_into(_state(robot, robot.q0, rng), out)
    assert out[0] == 0.0
