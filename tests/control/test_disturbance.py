"""Disturbance compensation of the inner controller (``controller.disturbance``)."""

from dataclasses import replace

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from amex.control.disturbance import (
    DisturbanceConfig,
    IntegralController,
    ObserverController,
    make_inner_controller,
)
from amex.control.osc import PD, Command, OperationalSpaceController, OSCGains
from amex.control.state import RobotState
from amex.core.errors import ConfigError
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.methods import METHODS
from amex.sim.episode import run_episode
from amex.sim.metrics import TIMING_COLUMNS
from amex.sim.scenario import make_scenario
from amex.sim.simulation import MismatchConfig, Simulation

DT = 1e-3
HOLD_GAINS = OSCGains(pos=PD(400.0, 40.0, 1.0), dir=PD(400.0, 40.0, 0.5))


def _hold(robot, inner, model, data, seconds, tau_ext=None):
    """Hold the start pose with ``inner``; return the last state's torque and TCP drift [m]."""
    pdata = robot.model.createData()
    target = robot.task_position(robot.q0)
    tau = np.zeros(robot.nv)
    for _ in range(int(round(seconds / DT))):
        state = RobotState(robot, pdata, data.qpos.copy(), data.qvel.copy())
        tau = inner.torque(state, Command(y=target, yd=np.zeros(6)))
        data.qfrc_applied[:] = tau if tau_ext is None else tau + tau_ext
        mujoco.mj_step(model, data)
    drift = np.linalg.norm(robot.task_position(data.qpos.copy())[:3] - target[:3])
    return tau, drift


def _world(robot, mismatch=None):
    """The simulated arm at its start pose, as an episode builds it (Task 0: no obstacles)."""
    start_tcp = robot.task_position(robot.q0)[:3]
    scenario = make_scenario(RunConfig().scene(), 0, 0, 0, start_tcp, 4.0)
    sim = Simulation(robot, scenario, 1.0 / DT, mismatch)
    return sim.model, sim.data


def _observer(robot, bandwidth=50.0, limit=0.5):
    osc = OperationalSpaceController(robot, HOLD_GAINS)
    config = DisturbanceConfig(kind="observer", bandwidth=bandwidth, limit=limit)
    inner = make_inner_controller(osc, DT, config)
    assert isinstance(inner, ObserverController)
    return inner


def test_observer_estimate_converges_to_a_constant_external_torque(robot):
    tau_ext = np.array([1.5, -2.0, 0.8, 1.2, 0.3, -0.4, 0.2])  # [N m], within the clamp
    inner = _observer(robot)
    model, data = _world(robot)
    _, drift = _hold(robot, inner, model, data, 1.0, tau_ext)
    # the estimate is the unmodelled torque with the sign of a disturbance, and it cancels it
    assert np.abs(inner.observer.r - tau_ext).max() < 1e-6
    assert drift < 1e-6


def test_observer_estimate_converges_to_the_unmodelled_weight_of_heavier_links(robot):
    inner = _observer(robot)
    model, data = _world(robot, MismatchConfig(mass_scale=1.2))
    _hold(robot, inner, model, data, 1.0)
    g = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), data.qpos.copy())
    # at rest M q_ddot + h = tau + tau_d on the 1.2x heavier arm gives tau_d = -0.2 g(q)
    assert np.abs(inner.observer.r - (-0.2 * g)).max() < 1e-6


def test_observer_follows_the_disturbance_at_its_bandwidth(robot):
    # r_dot = K_O (tau_d - r): after a step of tau_d the estimate has covered 1 - exp(-K_O t)
    bandwidth = 20.0
    tau_ext = np.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0])
    inner = _observer(robot, bandwidth=bandwidth)
    model, data = _world(robot)
    _hold(robot, inner, model, data, 0.05, tau_ext)
    covered = inner.observer.r[3] / 2.0
    assert covered == pytest.approx(1.0 - np.exp(-bandwidth * 0.05), abs=0.01)


def test_observer_estimate_stays_within_its_clamp_and_torques_within_limits(robot):
    limit = 0.1
    tau_ext = np.array([0.0, 30.0, 0.0, -30.0, 0.0, 0.0, 5.0])  # beyond 0.1 x (87, 87, 12) N m
    inner = _observer(robot, limit=limit)
    model, data = _world(robot)
    tau, _ = _hold(robot, inner, model, data, 0.5, tau_ext)
    bound = limit * robot.torque_limit
    assert np.all(np.abs(inner.observer.r) <= bound + 1e-12)
    assert np.allclose(np.abs(inner.observer.r[[1, 3, 6]]), bound[[1, 3, 6]])
    assert np.all(np.abs(tau) <= robot.torque_limit) and np.isfinite(data.qpos).all()


def test_integral_action_removes_the_steady_sag_of_heavier_links(robot):
    osc = OperationalSpaceController(robot, HOLD_GAINS)
    config = DisturbanceConfig(kind="integral", integral_gain=20.0, integral_limit=50.0)
    inner = make_inner_controller(osc, DT, config)
    assert isinstance(inner, IntegralController)
    mismatch = MismatchConfig(mass_scale=1.2)
    _, sag_pd = _hold(robot, osc, *_world(robot, mismatch), 2.0)
    _, sag_integral = _hold(robot, inner, *_world(robot, mismatch), 2.0)
    assert sag_pd > 1e-3 and sag_integral < 1e-2 * sag_pd


def test_integral_does_not_integrate_while_a_torque_saturates(robot):
    osc = OperationalSpaceController(robot, HOLD_GAINS)
    inner = IntegralController(osc, DT, DisturbanceConfig(kind="integral"))
    pdata = robot.model.createData()
    state = RobotState(robot, pdata, robot.q0.copy(), np.zeros(7))
    far = robot.task_position(robot.q0)
    far[:3] += 5.0  # saturates every step
    inner.torque(state, Command(y=far, yd=np.zeros(6)))
    z = inner.z_task.copy()
    for _ in range(10):
        inner.torque(state, Command(y=far, yd=np.zeros(6)))
    assert np.array_equal(inner.z_task, z)


def test_no_compensation_is_the_papers_controller_itself(robot):
    osc = OperationalSpaceController(robot, OSCGains())
    assert make_inner_controller(osc, DT, None) is osc
    assert make_inner_controller(osc, DT, DisturbanceConfig()) is osc


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("disturbance", "dob", "controller.disturbance='dob'; valid: none, observer, integral"),
        ("observer_bandwidth", 0.0, "controller.observer_bandwidth"),
        ("observer_limit", 1.5, "controller.observer_limit"),
        ("integral_gain", -1.0, "controller.integral_gain"),
        ("integral_limit", float("nan"), "controller.integral_limit"),
    ],
)
def test_invalid_compensation_settings_are_rejected(key, value, match):
    config = RunConfig()
    setattr(config.controller, key, value)
    with pytest.raises(ConfigError, match=match.replace("(", r"\(")):
        config.controller.compensation().validate()


@pytest.fixture(scope="module")
def nominal():
    config = RunConfig(task=1)
    config.method = METHODS["amex"].config_class()
    return config, prepare(config)


def test_switching_compensation_off_reproduces_the_episode_bit_for_bit(nominal):
    config, ctx = nominal
    scenario = make_scenario(config.scene(), 1, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = METHODS["amex"](ctx.plan, config.method, 0.01, ctx.robot)
    reference = ctx.plan.y[:, :3]
    plain = run_episode(
        ctx.robot, method, scenario, config.gains(), config.loop, reference_path=reference
    )
    via_runner = run_one(config, ctx, 0)  # the runner passes controller.disturbance=none
    timing = dict.fromkeys(TIMING_COLUMNS, 0.0)  # the machine's clocks, never equal
    assert replace(via_runner, **timing) == replace(plain, **timing)


@pytest.mark.parametrize("method", ["amex", "dmp", "cr"])
def test_observer_on_a_nominal_robot_changes_nominal_episodes_negligibly(method):
    config = RunConfig(task=2)
    config.method = METHODS[method].config_class()
    ctx = prepare(config)
    off = run_one(config, ctx, 0)
    config.controller.disturbance = "observer"
    on = run_one(config, ctx, 0)
    assert on.success == off.success and not on.failure
    assert on.final_time == pytest.approx(off.final_time, abs=2e-3)
    assert on.final_distance == pytest.approx(off.final_distance, abs=1e-4)
    assert on.sum_sq_acc == pytest.approx(off.sum_sq_acc, rel=1e-2)


@pytest.mark.parametrize(
    "mismatch",
    [
        MismatchConfig(mass_scale=0.1),
        MismatchConfig(mass_scale=3.0),
        MismatchConfig(friction=3.0),
        MismatchConfig(damping=20.0),
        MismatchConfig(mass_scale=3.0, friction=2.0, damping=5.0),
    ],
    ids=["light", "heavy", "friction", "damping", "all"],
)
def test_observer_reaches_the_goal_under_strong_mismatch(nominal, mismatch):
    # without compensation AMEX fails every one of these (Task 1, environment 0)
    config, ctx = nominal
    scenario = make_scenario(config.scene(), 1, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = METHODS["amex"](ctx.plan, config.method, 0.01, ctx.robot)
    compensation = DisturbanceConfig(kind="observer")
    result = run_episode(
        ctx.robot,
        method,
        scenario,
        config.gains(),
        config.loop,
        mismatch=mismatch,
        disturbance=compensation,
    )
    assert not result.failure
    assert result.success


def test_observer_degrades_gracefully_when_the_arm_cannot_carry_its_own_weight(robot):
    # 6x heavier links need more than the joint torque limits just to hold the start pose
    inner = _observer(robot)
    model, data = _world(robot, MismatchConfig(mass_scale=6.0))
    tau, _ = _hold(robot, inner, model, data, 1.0)
    assert np.all(np.abs(inner.observer.r) <= robot.torque_limit)
    assert np.all(np.abs(tau) <= robot.torque_limit)
    assert np.isfinite(data.qpos).all() and np.isfinite(data.qvel).all()


def test_an_unknown_compensation_is_a_config_error_naming_the_choices():
    from amex.app.compose import load_config

    with pytest.raises(ConfigError, match="controller.disturbance='dob'; valid: none, observer"):
        load_config(["controller.disturbance=dob"])


def test_compensation_is_refused_in_a_kinematic_simulation():
    from amex.app.compose import load_config

    with pytest.raises(ConfigError, match="disturbance='observer' with sim=kinematic"):
        load_config(["sim=kinematic", "controller.disturbance=observer"])
