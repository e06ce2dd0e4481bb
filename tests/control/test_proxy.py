"""The authors' collision task (``controller.collision_cost=proxy``): value, Jacobian, checks."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from amex.control.collision import CollisionModel
from amex.control.osc import PD, Command, ControllerGains, OperationalSpaceController, OSCGains
from amex.control.state import RobotState
from amex.control.tasks import CollisionMap, ProxyMap
from amex.core.errors import ConfigError
from amex.robot import RobotConfig, load_robot

EPS = 1e-6
#: (robot, margin [m], obstacle radius [m]): the authors' chain at scale 1, the Panda at 0.2.
ROBOTS = {"chain7": (0.1, 0.1), "panda": (0.02, 0.02)}


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def arm(request):
    return request.param, load_robot(RobotConfig(name=request.param))


def _state(robot, q):
    return RobotState(robot, robot.model.createData(), q, np.zeros(robot.nv))


def _capsule_frame(robot, q, c):
    """World centre and axis of capsule ``c`` at ``q``."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    cap = robot.capsules[c]
    M = data.oMi[cap.joint_id] * cap.placement
    return M.translation.copy(), M.rotation[:, 2].copy()


def _beside(robot, q, c, gap, radius, rng):
    """An obstacle centre ``gap`` [m] from capsule ``c``'s surface, beside its middle."""
    center, axis = _capsule_frame(robot, q, c)
    side = np.cross(axis, rng.normal(size=3))
    side /= np.linalg.norm(side)
    return center + (robot.capsules[c].radius + radius + gap) * side


def _case(robot, margin, radius, seed):
    """A configuration and an obstacle with a pair inside the margin, none at a kink."""
    rng = np.random.default_rng(seed)
    for _ in range(100):
        q = robot.q0 + rng.normal(scale=0.2, size=robot.nv)
        c = int(rng.integers(1, len(robot.capsules)))
        collision = CollisionModel(robot, [radius])
        collision.set_obstacles(
            _beside(robot, q, c, rng.uniform(0.2, 0.8) * margin, radius, rng)[None]
        )
        d = np.array([p.distance for p in collision.proximities(_state(robot, q).data, 10.0)])
        kinks = np.abs(np.concatenate([d, d - margin])).min()
        if kinks > 1e-4 and np.any((d > 0) & (d < margin)):
            return q, collision
    raise AssertionError("no case found")


def _fd_jacobian(robot, f, q):
    cols = []
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = EPS
        plus, minus = pin.integrate(robot.model, q, dq), pin.integrate(robot.model, q, -dq)
        cols.append((f(plus) - f(minus)) / (2 * EPS))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_proxy_jacobian_matches_finite_differences(arm, seed):
    name, robot = arm
    margin, radius = ROBOTS[name]
    q, collision = _case(robot, margin, radius, seed)
    proxy = ProxyMap(collision, margin, (), radius)
    terms = proxy.evaluate(_state(robot, q))
    assert terms.phi[0] > 0
    J_fd = _fd_jacobian(robot, lambda x: proxy.evaluate(_state(robot, x)).phi.copy(), q)
    assert np.abs(terms.J - J_fd).max() < 1e-5


def _their_value(robot, collision, q, margin, arm_radii, obstacle_radius):
    """``sum_p (1 - d_p / m)(1 - c_p / a_p)`` pair by pair, with coal's distance of each pair."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    obstacle = collision.obstacle_center(0)
    total = 0.0
    for c, cap in enumerate(robot.capsules):
        M = data.oMi[cap.joint_id] * cap.placement
        shape = (
            coal.Capsule(cap.radius, 2 * cap.half_length)
            if cap.half_length
            else coal.Sphere(cap.radius)
        )
        result = coal.DistanceResult()
        arm_pose = coal.Transform3s(M.rotation, M.translation)
        obstacle_pose = coal.Transform3s(np.eye(3), obstacle)
        ball = coal.Sphere(collision.radii[0])
        coal.distance(shape, arm_pose, ball, obstacle_pose, coal.DistanceRequest(), result)
        d = result.min_distance
        if d < margin:
            reach = margin + 1.5 * (arm_radii[c] + obstacle_radius)
            total += (1 - max(d, 0.0) / margin) * (
                1 - np.linalg.norm(M.translation - obstacle) / reach
            )
    return total


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_proxy_value_is_the_authors_sum_over_the_pairs_in_the_margin(arm, seed):
    name, robot = arm
    margin, radius = ROBOTS[name]
    q, collision = _case(robot, margin, radius, seed)
    radii = [c.half_length + c.radius for c in robot.capsules]
    phi = ProxyMap(collision, margin, (), radius).evaluate(_state(robot, q)).phi[0]
    assert phi == pytest.approx(_their_value(robot, collision, q, margin, radii, radius), rel=1e-12)


def test_on_the_chain_one_link_beside_the_obstacle_gives_their_closed_form():
    robot = load_robot(RobotConfig(name="chain7"))
    q, gap, m = robot.q0.copy(), 0.03, 0.1
    collision = CollisionModel(robot, [0.1])
    collision.set_obstacles(_beside(robot, q, 2, gap, 0.1, np.random.default_rng(0))[None])
    proxy = ProxyMap(collision, m, [0.3] * 6 + [0.0002], 0.1)
    (prox,) = collision.proximities(_state(robot, q).data, m)  # link 3 alone
    assert prox.shape == 2 and prox.distance == pytest.approx(gap, abs=1e-12)
    expected = (1 - gap / m) * (1 - (0.1 + 0.1 + gap) / (m + 1.5 * (0.3 + 0.1)))
    assert proxy.evaluate(_state(robot, q)).phi[0] == pytest.approx(expected, rel=1e-12)


def test_default_radii_are_the_bounding_radii_theirs_on_the_chain():
    robot = load_robot(RobotConfig(name="chain7"))
    proxy = ProxyMap(CollisionModel(robot, [0.1]), 0.1, (), 0.1)
    explicit = ProxyMap(CollisionModel(robot, [0.1]), 0.1, [0.3] * 6 + [0.0002], 0.1)
    np.testing.assert_allclose(proxy.reach, explicit.reach, rtol=1e-12)
    assert proxy.reach[0] == pytest.approx(0.1 + 1.5 * 0.4)  # a link: 0.7 m
    assert proxy.reach[6] == pytest.approx(0.1 + 1.5 * 0.1002)  # the TCP


def test_a_penetrating_pair_counts_at_distance_zero_and_moves_by_its_centres():
    robot = load_robot(RobotConfig(name="chain7"))
    q = robot.q0.copy()
    collision = CollisionModel(robot, [0.1])
    collision.set_obstacles(_beside(robot, q, 2, -0.05, 0.1, np.random.default_rng(1))[None])
    proximities = collision.proximities(_state(robot, q).data, 0.1)
    assert min(p.distance for p in proximities) < 0 < max(p.distance for p in proximities)
    proxy = ProxyMap(collision, 0.1, (), 0.1)
    terms = proxy.evaluate(_state(robot, q))
    radii = [0.3] * 6 + [0.0002]
    assert terms.phi[0] == pytest.approx(_their_value(robot, collision, q, 0.1, radii, 0.1))
    J_fd = _fd_jacobian(robot, lambda x: proxy.evaluate(_state(robot, x)).phi.copy(), q)
    assert np.abs(terms.J - J_fd).max() < 1e-5  # d1 = 1 there: the centre term alone


def test_the_controller_uses_the_proxy_only_when_asked(robot):
    collision = CollisionModel(robot, [0.02])
    assert type(OperationalSpaceController(robot, OSCGains(), collision).col_map) is CollisionMap
    proxy = OperationalSpaceController(robot, OSCGains(collision_cost="proxy"), collision)
    assert type(proxy.col_map) is ProxyMap


def test_bad_proxy_settings_raise_config_errors(robot):
    collision = CollisionModel(robot, [0.02])
    with pytest.raises(ConfigError, match="proxy_arm_radii"):
        ProxyMap(collision, 0.02, [0.1, 0.2])
    with pytest.raises(ConfigError, match="proxy_obstacle_radius"):
        ProxyMap(collision, 0.02, (), 0.0)
    with pytest.raises(ConfigError, match="collision_cost.*hinge"):
        ControllerGains(collision_cost="cone").validate()
    with pytest.raises(ConfigError, match="collision_cost"):
        OperationalSpaceController(robot, OSCGains(collision_cost="cone"), collision)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_objective_with_the_proxy_equals_task_by_task_objective(robot, seed):
    rng = np.random.default_rng(seed)
    q, collision = _case(robot, 0.02, 0.02, seed)
    gains = OSCGains(damping=PD(3.0, 10.0, 0.01), collision_cost="proxy", margin=0.02)
    osc = OperationalSpaceController(robot, gains, collision)
    state = RobotState(robot, robot.model.createData(), q, rng.normal(size=7))
    assert osc.col_map.evaluate(state).phi[0] > 0
    command = Command(y=state.y + rng.normal(scale=0.01, size=6), yd=rng.normal(size=6))
    fast, slow = osc.build_objective(state, command), osc.build_objective_reference(state, command)
    assert np.allclose(fast.A, slow.A, rtol=1e-12, atol=1e-10)
    assert np.allclose(fast.b, slow.b, rtol=1e-12, atol=1e-10)
