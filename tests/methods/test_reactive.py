"""The reactive methods of issue #26: rmpflow, cbf_ik, amex_cbf and dmp_avoid.

Finite-difference checks of every hand-written derivative (the clearance's gradient, obstacle
rate and drift, the axis Jacobian and its drift, the barrier rows, Park's potential gradient, the
coupling's step response), the controllers' properties (at the target the command is zero, from
a perturbed start the error falls below tolerance) and short real episodes on Tasks 0-4.

Real robot, planner, MuJoCo, Pinocchio and coal (the ``robot`` fixture of ``conftest.py``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from amex.core.errors import ConfigError
from amex.core.scaling import to_scene_units
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.methods import (
    CBFIK,
    DMP,
    METHODS,
    AMEXCBFConfig,
    CBFIKConfig,
    DMPAvoid,
    DMPAvoidConfig,
    DMPConfig,
    RMPflow,
    RMPflowConfig,
)
from amex.methods import rmpflow_leaves as leaves
from amex.methods.barrier import BarrierConfig, BarrierQP, build_barrier_qp, solve_barrier_qp
from amex.methods.base import Observation
from amex.methods.cbf_ik import goal_velocity
from amex.methods.clearance import ArmSensor
from amex.methods.dmp_avoid import potential, response_to_constant_acceleration, steering
from amex.robot.geometry import skew
from amex.sim.episode import run_episode
from amex.sim.scenario import make_scenario

DT = 0.01
SCALE = RunConfig().scenario.scale
NEW = ("rmpflow", "cbf_ik", "amex_cbf", "dmp_avoid")
CONFIGS = {"rmpflow": RMPflowConfig, "cbf_ik": CBFIKConfig, "amex_cbf": AMEXCBFConfig,
           "dmp_avoid": DMPAvoidConfig}  # fmt: skip


def scene(config):
    """``config`` in the Panda scene's units (lengths given in original units x 0.2)."""
    return to_scene_units(config, SCALE)


@pytest.fixture(scope="module")
def context():
    config = RunConfig()
    return config, prepare(config)


def near_obstacle(robot, q, offset=(0.06, 0.02, -0.03), radius=0.02):
    """One obstacle ``offset`` [m] from the TCP at ``q`` (a few cm from the hand)."""
    y = robot.task_position(q)
    return np.asarray(y[:3] + np.asarray(offset))[None, :], np.array([radius])


def observe(robot, t, q, qd=None, goal=None, obstacles=None, radii=None) -> Observation:
    q = np.asarray(q, dtype=float)
    qd = np.zeros(len(q)) if qd is None else np.asarray(qd, dtype=float)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q, qd)
    y = robot.task_position(q)
    goal = y + [0.05, 0.1, -0.05, 0.0, 0.0, 0.0] if goal is None else goal
    obstacles = np.zeros((0, 3)) if obstacles is None else obstacles
    radii = np.full(len(obstacles), 0.02) if radii is None else radii
    return Observation(t=t, q=q, qd=qd, y=y, yd=np.zeros(6), goal=np.asarray(goal, dtype=float),
                       obstacles=obstacles, obstacle_radii=radii)  # fmt: skip


def pair_distances(robot, q, centers, radii, activation=1.0):
    """Every pair's distance at ``q`` (sorted by (obstacle, gradient row) as the sensor's)."""
    snap = ArmSensor(robot).measure(0.0, q, np.zeros(robot.nv), centers, radii, activation)
    return snap.pairs.distance


def test_the_new_methods_are_registered_with_their_configs():
    for name in NEW:
        assert METHODS[name].name == name and METHODS[name].config_class is CONFIGS[name]
        assert CONFIGS[name]().name == name


# ----------------------------------------------------------------------------- clearance
def test_the_pair_gradient_is_the_finite_difference_of_the_distance(robot):
    q = robot.q0.copy()
    centers, radii = near_obstacle(robot, q)
    snap = ArmSensor(robot).measure(0.0, q, np.zeros(robot.nv), centers, radii, 1.0)
    assert len(snap.pairs.distance) >= 3  # the hand and the last links are close
    h = 1e-6
    for j in range(robot.nv):
        e = np.zeros(robot.nv)
        e[j] = h
        fd = (pair_distances(robot, q + e, centers, radii)
              - pair_distances(robot, q - e, centers, radii)) / (2 * h)  # fmt: skip
        np.testing.assert_allclose(snap.pairs.gradient[:, j], fd, atol=2e-5)


def test_the_obstacle_rate_is_the_distance_change_of_the_moving_obstacle(robot):
    q = robot.q0.copy()
    centers, radii = near_obstacle(robot, q)
    v = np.array([[0.03, -0.05, 0.02]])
    h = 1e-3
    sensor = ArmSensor(robot)
    sensor.measure(0.0, q, np.zeros(robot.nv), centers, radii, 1.0)
    snap = sensor.measure(h, q, np.zeros(robot.nv), centers + v * h, radii, 1.0)
    eps = 1e-6
    fd = (pair_distances(robot, q, centers + v * (h + eps), radii)
          - pair_distances(robot, q, centers + v * (h - eps), radii)) / (2 * eps)  # fmt: skip
    np.testing.assert_allclose(snap.pairs.rate, fd, atol=1e-6)


@pytest.mark.parametrize("offset", [(0.0, 0.0, -0.06), (0.06, 0.02, -0.03)])
def test_the_pair_drift_is_the_second_difference_along_a_straight_joint_motion(robot, offset):
    q = robot.q0.copy()
    qd = np.random.default_rng(2).uniform(-2.0, 2.0, robot.nv)
    centers, radii = near_obstacle(robot, q, offset=offset)  # hand, fingers, wrist: caps, cylinders
    snap = ArmSensor(robot).measure(0.0, q, qd, centers, radii, 1.0, drift=True)
    h = 3e-3
    d = [pair_distances(robot, q + s * h * qd, centers, radii) for s in (-1, 0, 1)]
    fd = (d[0] - 2 * d[1] + d[2]) / h**2
    assert np.abs(fd).max() > 0.5  # a real curvature to check
    np.testing.assert_allclose(snap.pairs.drift, fd, rtol=0.01, atol=0.01)


def test_the_axis_jacobian_and_its_drift_are_the_derivatives_of_the_tcp_axis(robot):
    q = robot.q0 + 0.1
    qd = np.linspace(-0.4, 0.4, robot.nv)
    snap = ArmSensor(robot).measure(0.0, q, qd, np.zeros((0, 3)), np.zeros(0), 1.0)
    state = snap.state
    Jz = -skew(state.tcp_axis) @ state.J[3:]
    h = 1e-6
    z = lambda q_: robot.task_position(q_)[3:]  # noqa: E731
    for j in range(robot.nv):
        e = np.zeros(robot.nv)
        e[j] = h
        np.testing.assert_allclose(Jz[:, j], (z(q + e) - z(q - e)) / (2 * h), atol=1e-7)
    # z_ddot at q_ddot = 0 (RMPflow's axis leaf): alpha x z + w x (w x z)
    w = state.J[3:] @ qd
    zd = np.cross(w, z(q))
    drift = np.cross(state.acc_drift[3:], z(q)) + np.cross(w, zd)
    H = 1e-4
    fd = (z(q + H * qd) - 2 * z(q) + z(q - H * qd)) / H**2
    np.testing.assert_allclose(drift, fd, atol=1e-5)
    p = lambda q_: robot.task_position(q_)[:3]  # noqa: E731
    fd_p = (p(q + H * qd) - 2 * p(q) + p(q - H * qd)) / H**2
    np.testing.assert_allclose(state.acc_drift[:3], fd_p, atol=1e-5)  # the goal leaf's drift


# ----------------------------------------------------------------------------- RMPflow
def test_the_resolved_rmp_is_the_pullback_of_every_leaf(robot):
    method = RMPflow(prepare(RunConfig()).plan, scene(RMPflowConfig()), DT, robot)
    q = robot.q0 + 0.05
    qd = np.linspace(-0.2, 0.3, robot.nv)
    centers, radii = near_obstacle(robot, q)
    snap = method.sensor.measure(0.0, q, qd, centers, radii, method.config.obstacle_radius,
                                 drift=True)  # fmt: skip
    goal = robot.task_position(robot.q0) + [0.05, 0.0, 0.02, 0.0, 0.0, 0.0]
    out = method.resolve_leaves(snap, goal)
    compiled = method.resolve(snap, goal)  # the kernel computes the same leaves
    np.testing.assert_allclose(compiled.metric, out.metric, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(compiled.force, out.force, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(compiled.qdd, out.qdd, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(out.metric, out.metric.T, atol=1e-12)
    assert np.linalg.eigvalsh(out.metric).min() > 0.0  # the damping leaf's inertia
    np.testing.assert_allclose(out.metric @ out.qdd, out.force, rtol=1e-8, atol=1e-10)
    # without the obstacle its leaves' share is gone: the pullback of the pairs is additive
    bare = method.resolve_leaves(snap._replace(pairs=snap.pairs._replace(
        distance=snap.pairs.distance[:0], gradient=snap.pairs.gradient[:0],
        rate=snap.pairs.rate[:0], drift=snap.pairs.drift[:0])), goal)  # fmt: skip
    G = snap.pairs.gradient
    rmp = leaves.obstacle_avoidance(snap.pairs.distance, G @ qd + snap.pairs.rate,
                                    *method._obstacle)  # fmt: skip
    np.testing.assert_allclose(out.metric - bare.metric, G.T @ (rmp.metric[:, None] * G),
                               atol=1e-9)  # fmt: skip
    np.testing.assert_allclose(
        out.force - bare.force, G.T @ (rmp.metric * (rmp.accel - snap.pairs.drift)), atol=1e-9
    )


def test_the_obstacle_leaf_pushes_away_and_its_metric_vanishes_at_the_radius():
    args = (0.0, 800.0, 0.01, 50.0, 0.04, 0.01, 0.05, 0.5, 1.0, 0.02, 0.001)
    d = np.array([0.01, 0.1, 0.49, 0.5, 0.7])
    rmp = leaves.obstacle_avoidance(d, -0.1 * np.ones(5), *args)
    assert (rmp.accel > 0).all()  # repulsion and braking of the approach
    assert (rmp.metric[:3] > 0).all() and (rmp.metric[3:] == 0).all()
    assert rmp.metric[0] > rmp.metric[1] > rmp.metric[2]
    leaving = leaves.obstacle_avoidance(d, 0.5 * np.ones(5), *args)
    assert (leaving.metric < rmp.metric + 1e-15).all()  # the gate: moving away matters less


def test_rmpflow_at_rest_on_the_goal_at_its_rest_posture_commands_no_motion(robot, context):
    _, ctx = context
    method = RMPflow(ctx.plan, scene(RMPflowConfig()), DT, robot)
    goal = robot.task_position(robot.q0)
    obs = observe(robot, 0.0, robot.q0, goal=goal)
    method.reset(obs)
    command = method.step(obs)
    assert np.abs(method.internals()["qdd"]).max() < 1e-2  # only the joint limits' faint push
    assert np.abs(command.qd).max() < 1e-4 and np.abs(command.q - robot.q0).max() < 1e-6


# ----------------------------------------------------------------------------- barrier
def filter_config(**changes) -> BarrierConfig:
    return to_scene_units(dataclasses.replace(BarrierConfig(), **changes), SCALE)


def test_the_barrier_rows_are_the_distance_rate_and_hold_at_the_solution(robot):
    q = robot.q0.copy()
    centers, radii = near_obstacle(robot, q, offset=(0.04, 0.0, 0.0))
    config = filter_config()
    snap = ArmSensor(robot).measure(0.0, q, np.zeros(robot.nv), centers, radii,
                                    config.activation_distance)  # fmt: skip
    q_lo, q_hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    speed = np.asarray(robot.velocity_limit)
    v = np.zeros(6)
    v[:3] = 0.5 * (centers[0] - snap.state.tcp_pos)  # straight at the obstacle
    qp = build_barrier_qp(snap, v, config, q_lo, q_hi, speed)
    sol = solve_barrier_qp(qp, config.solver, config.slack_weight)
    assert sol.slack == 0.0 and sol.active >= 1
    # the row is the first-order distance change: d(q + u h) - d(q) = h grad d u
    h = 1e-6
    d_rate = (pair_distances(robot, q + h * sol.qd, centers, radii, config.activation_distance)
              - snap.pairs.distance) / h  # fmt: skip
    np.testing.assert_allclose(d_rate, snap.pairs.gradient @ sol.qd, atol=1e-5)
    assert (d_rate >= -config.barrier_gain * (snap.pairs.distance - config.safety_distance)
            - 1e-5).all()  # fmt: skip
    assert (sol.qd >= qp.lb - 1e-9).all() and (sol.qd <= qp.ub + 1e-9).all()
    # without obstacles the QP is the damped least-squares IK of the nominal velocity
    free = snap._replace(pairs=snap.pairs._replace(distance=snap.pairs.distance[:0],
                         gradient=snap.pairs.gradient[:0], rate=snap.pairs.rate[:0]))  # fmt: skip
    qp0 = build_barrier_qp(free, v, config, q_lo, q_hi, speed)
    u0 = solve_barrier_qp(qp0, config.solver, config.slack_weight).qd
    if ((u0 > qp0.lb + 1e-9) & (u0 < qp0.ub - 1e-9)).all():
        np.testing.assert_allclose(u0, np.linalg.solve(qp0.P, -qp0.c), atol=1e-8)


def test_an_infeasible_barrier_qp_is_relaxed_by_a_slack():
    P, c = np.eye(2), np.zeros(2)
    G = np.array([[1.0, 0.0]])  # u0 <= -1 against u0 >= -0.5
    qp = BarrierQP(P, c, G, np.array([-1.0]), np.array([-0.5, -1.0]), np.array([1.0, 1.0]))
    sol = solve_barrier_qp(qp, "daqp", 1e6)
    assert sol.slack == pytest.approx(0.5, abs=1e-5) and sol.qd[0] == pytest.approx(-0.5)


def test_cbf_ik_at_rest_on_the_goal_commands_no_motion(robot, context):
    _, ctx = context
    method = CBFIK(ctx.plan, scene(CBFIKConfig()), DT, robot)
    obs = observe(robot, 0.0, robot.q0, goal=robot.task_position(robot.q0))
    method.reset(obs)
    command = method.step(obs)
    np.testing.assert_allclose(command.qd, 0.0, atol=1e-9)
    np.testing.assert_allclose(command.q, robot.q0, atol=1e-12)


def test_the_nominal_velocity_is_capped_and_zero_at_the_goal():
    p, z = np.zeros(3), np.array([0.0, 0.0, 1.0])
    goal = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    v = goal_velocity(p, z, goal, 2.0, 0.25, 2.0)
    assert np.linalg.norm(v[:3]) == pytest.approx(0.25) and (v[3:] == 0).all()
    assert (goal_velocity(goal[:3], z, goal, 2.0, 0.25, 2.0) == 0).all()


# ----------------------------------------------------------------------------- dmp_avoid
def park_potential(y, yd, center, radius, gain, power, min_distance):
    """Park et al.'s dynamic potential U (module notes of amex.methods.dmp_avoid)."""
    rel = y - center
    dist = np.linalg.norm(rel)
    cos = float(yd @ rel) / (np.linalg.norm(yd) * dist)
    if cos >= 0.0:
        return 0.0
    p = max(dist - radius, min_distance)
    return gain * (-cos) ** power * np.linalg.norm(yd) / p


def test_parks_coupling_is_minus_the_gradient_of_the_potential():
    center, radius = np.array([0.1, 0.0, 0.0]), 0.02
    yd = np.array([0.2, 0.05, -0.03])
    for y in (np.array([0.0, 0.01, 0.0]), np.array([0.02, -0.03, 0.01])):
        C = potential(y, yd, center, radius, 1.0, 2.0, 0.005)
        h = 1e-7
        fd = np.array([(park_potential(y + e, yd, center, radius, 1.0, 2.0, 0.005)
                        - park_potential(y - e, yd, center, radius, 1.0, 2.0, 0.005)) / (2 * h)
                       for e in h * np.eye(3)])  # fmt: skip
        np.testing.assert_allclose(C, -fd, rtol=1e-5, atol=1e-6)
    assert (potential(np.zeros(3), -yd, center, radius, 1.0, 2.0, 0.005) == 0).all()  # leaving


def test_hoffmanns_steering_turns_the_velocity_away_from_the_obstacle():
    y, center = np.zeros(3), np.array([0.1, 0.02, 0.0])
    yd = np.array([0.3, 0.0, 0.0])
    C = steering(y, yd, center, 0.02, 250.0, 20.0 / math.pi, 0.0)
    phi = math.acos(float(yd @ center) / (np.linalg.norm(yd) * np.linalg.norm(center)))
    assert abs(C @ yd) < 1e-12  # perpendicular to the velocity
    assert C @ (center - y) < 0  # away from the obstacle
    expected = 250.0 * phi * math.exp(-20.0 / math.pi * phi) * np.linalg.norm(yd)
    assert np.linalg.norm(C) == pytest.approx(expected)
    far = steering(y, yd, center * 10, 0.02, 250.0, 20.0 / math.pi, 0.02)
    assert np.linalg.norm(far) < 1e-10 * np.linalg.norm(C) + 1e-15  # the distance decay
    assert (steering(y, np.zeros(3), center, 0.02, 250.0, 1.0, 0.0) == 0).all()  # at rest


def test_the_coupling_step_is_the_integrated_response_to_a_constant_acceleration():
    alpha, beta, tau, h = 25.0, 6.25, 4.0, 0.01
    gamma = response_to_constant_acceleration(alpha, beta, tau, h)
    x, n = np.zeros(2), 20000  # RK4 of y_ddot = -ab/tau^2 y - a/tau y_dot + 1 from rest
    f = lambda x: np.array([x[1], -alpha * beta / tau**2 * x[0] - alpha / tau * x[1] + 1.0])  # noqa: E731
    for _ in range(n):
        k1 = f(x)
        k2 = f(x + h / n / 2 * k1)
        k3 = f(x + h / n / 2 * k2)
        k4 = f(x + h / n * k3)
        x = x + h / n / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(gamma, x, rtol=1e-9)


def test_without_obstacles_dmp_avoid_is_the_dmp_bit_for_bit(robot, context):
    _, ctx = context
    dmp = DMP(ctx.plan, scene(DMPConfig()), DT, robot)
    avoid = DMPAvoid(ctx.plan, scene(DMPAvoidConfig()), DT, robot)
    obs = observe(robot, 0.0, robot.q0, goal=ctx.plan.goal)
    dmp.reset(obs)
    avoid.reset(obs)
    for k in range(50):
        step = dataclasses.replace(obs, t=k * DT)
        a, b = dmp.step(step), avoid.step(step)
        np.testing.assert_array_equal(a.y, b.y)
        np.testing.assert_array_equal(a.yd, b.yd)


def test_dmp_avoid_settings_it_cannot_run_with_are_refused():
    with pytest.raises(ConfigError, match="coupling"):
        DMPAvoidConfig(coupling="magnet").validate()
    with pytest.raises(ConfigError, match="activation_distance"):
        CBFIKConfig(activation_distance=0.01, safety_distance=0.05).validate()
    with pytest.raises(ConfigError, match="solver"):
        AMEXCBFConfig(solver="cplex").validate()
    with pytest.raises(ConfigError, match="goal_boost"):
        RMPflowConfig(goal_boost=0.5).validate()


# ----------------------------------------------------------------------------- episodes
@pytest.mark.parametrize("name", NEW)
def test_from_a_perturbed_start_on_task_0_the_error_falls_below_the_stop_radius(robot, context,
                                                                                 name):  # fmt: skip
    config, ctx = context
    rng = np.random.default_rng(5)
    moved = dataclasses.replace(robot, q0=robot.q0 + rng.uniform(-0.15, 0.15, robot.nv))
    scenario = make_scenario(config.scene(), 0, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = METHODS[name](ctx.plan, scene(CONFIGS[name]()), DT, robot)
    result = run_episode(moved, method, scenario, config.gains(), config.loop)
    assert result.failure == "" and result.success and not result.collided
    assert result.final_distance <= config.loop.stop_radius + 1e-3


@pytest.mark.parametrize("task", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("name", NEW)
def test_short_episodes_of_every_task_reach_the_goal_without_contact(context, name, task):
    config, _ = context
    config = dataclasses.replace(config, task=task, max_time=8.0)
    config.method = CONFIGS[name]()
    ctx = prepare(config)
    result = run_one(config, ctx, 0)
    assert result.success and not result.failure and not result.collided, (name, task)
    if task >= 3:
        assert result.min_clearance > 0.0


# ----------------------------------------------------------------------------- the study
def _study_jobs(*arguments: str) -> list[list[str]]:
    from amex.app.checks import sweep_settings
    from amex.app.sweeps import sweep_jobs

    params, grids, shards, _ = sweep_settings(["study=baselines", *arguments], [])
    return sweep_jobs(params, grids, ["study=baselines", *arguments], shards)


def _cell(job: list[str]) -> tuple[str, str, str]:
    values = dict(o.split("=", 1) for o in job)
    return values["method"], values["robot"], values["task"]


def test_the_study_runs_every_method_robot_and_task_once_in_its_own_directory():
    jobs = _study_jobs()
    cells = [_cell(job) for job in jobs]
    assert len(cells) == len(set(cells)) == 8 * 3 * 4
    episodes = {_cell(j)[1]: dict(o.split("=", 1) for o in j)["episodes"] for j in jobs}
    assert episodes == {"panda": "150", "ur5": "30", "chain7": "30"}


def test_one_method_of_the_study_runs_only_its_own_cells():
    cells = [_cell(job) for job in _study_jobs("method=mppi")]
    assert len(cells) == 12 and {m for m, _, _ in cells} == {"mppi"}
    assert set(cells) <= {_cell(job) for job in _study_jobs()}
