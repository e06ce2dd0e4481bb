"""The compiled step of the episode loop against its oracle, the loop in Python and numpy."""

import dataclasses
import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from amex.app.compose import load_config
from amex.control.osc import Command
from amex.experiment.runner import prepare, setup
from amex.sim import step_kernel as sk
from amex.sim.episode import _run
from amex.sim.episode_reference import run_reference
from amex.sim.episode_setup import Episode
from amex.sim.inner_step import StepMemory
from amex.sim.scenario import make_scenario

#: the timing columns (the only ones that may differ between two runs of an episode)
_TIMES = {
    "compute_time_median",
    "compute_time_mean",
    "compute_cpu_median",
    "compute_cpu_mean",
    "compute_cpu_p95",
    "compute_cpu_max",
    "deadline_misses",
}


def _episodes(task, method, env, overrides=()):
    """A maker of fresh, identical episodes (method instance, scenario, simulator) of a run."""
    config = load_config([f"method={method}", f"task={task}", *overrides])
    run = setup(config, prepare(config))
    ctx = run.context

    def make():
        instance = run.method(ctx.plan, run.params, run.outer_dt, ctx.robot)
        scenario = make_scenario(
            run.scene, task, run.seed, env, ctx.plan.y[0, :3], ctx.plan.duration
        )
        world = {**run.world, "reference_path": ctx.plan.y[:, :3]}
        return Episode(ctx.robot, instance, scenario, run.gains, run.loop, **world)

    return make


def _same(a, b):
    return a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))


@pytest.mark.parametrize(
    ("task", "method", "env", "overrides"),
    [
        (0, "amex", 0, ()),  # no obstacle, static goal
        (3, "amex", 0, ()),  # moving goal, obstacle: the hinge collision task in and out of use
        (3, "dmp", 1, ()),
        (4, "amex", 2, ()),  # moving obstacle
        (3, "cr", 0, ("max_time=2",)),  # joint targets with the damping and collision tasks
        (3, "amex", 0, ("experiment=original",)),  # kinematic, state lag, the proxy task
        (3, "cr", 1, ("experiment=original",)),  # the joint task alone, CR ends the episode
        (3, "amex", 1, ("controller.disturbance=observer", "max_time=2")),  # not compiled
        (3, "amex", 0, ("experiment=pr2_like", "max_time=2")),  # noise, latency, mismatch
    ],
)
def test_compiled_loop_gives_the_python_loop_bit_for_bit(task, method, env, overrides):
    make = _episodes(task, method, env, overrides)
    compiled, oracle = make(), make()
    compiled.q_history[:] = oracle.q_history[:] = 0.0  # (rows after the last step stay unwritten)
    got, want = _run(compiled, None), run_reference(oracle, None)
    assert np.array_equal(compiled.q_history, oracle.q_history)
    fields = [f.name for f in dataclasses.fields(got) if f.name not in _TIMES]
    differ = {f: (getattr(got, f), getattr(want, f)) for f in fields}
    differ = {f: pair for f, pair in differ.items() if not _same(*pair)}
    assert differ == {}


@pytest.mark.parametrize(
    ("at", "failure"),
    [
        (5, "solver: OSC normal equations not positive definite (info=1)"),  # an inner step
        (10, "solver: non-finite q: [nan nan nan nan nan nan nan]"),  # an outer step's check
    ],
)
def test_compiled_loop_ends_on_a_nan_state_as_the_python_loop_does(at, failure):
    def nan_joints(k, data):
        if k == at:
            data.qpos[:] = np.nan

    make = _episodes(3, "amex", 0, ("max_time=0.2",))
    got, want = _run(make(), None, nan_joints), run_reference(make(), None, nan_joints)
    assert got.failure == want.failure == failure
    fields = [f.name for f in dataclasses.fields(got) if f.name not in _TIMES]
    assert all(_same(getattr(got, f), getattr(want, f)) for f in fields)


def _memory(robot, in_place=True, task=3):
    """A StepMemory over a fresh episode's arrays, and that episode."""
    episode = _episodes(task, "amex", 0)()
    data = robot.model.createData()
    mjd = episode.sim.data
    memory = StepMemory(
        robot, data, episode.osc, episode.collision, episode.scenario, episode.loop, episode.dt,
        episode.q_history, mjd.qpos, mjd.qvel, mjd.qfrc_applied, in_place=in_place,
    )  # fmt: skip
    return memory, episode, data


def _kinematics(robot, data, q, v):
    pin.forwardKinematics(robot.model, data, q, v, robot.zero_velocity)
    pin.computeJointJacobians(robot.model, data)
    pin.updateFramePlacement(robot.model, data, robot.tcp_frame_id)


def test_step_memory_reads_the_tcp_placement_and_jacobians_in_place(robot):
    memory, _, data = _memory(robot)
    assert memory.zero_copy  # this install's Pinocchio: views, no copies
    _kinematics(robot, data, robot.q0 + 0.3, np.ones(7))
    placement = data.oMf[robot.tcp_frame_id]
    view = memory._tcp.reshape(4, 3).T
    assert np.array_equal(view[:, :3], placement.rotation)
    assert np.array_equal(view[:, 3], placement.translation)
    assert np.array_equal(memory._joint_jacobians, data.J)


@pytest.mark.parametrize("in_place", [True, False])
def test_measure_phase_gives_the_python_path_length_goal_and_distance(robot, in_place):
    """Python floats with ``**`` (the C library's pow) are the oracle: 300 random steps."""
    memory, episode, data = _memory(robot, in_place)
    scenario, rng = episode.scenario, np.random.default_rng(3)
    qpos = episode.sim.data.qpos
    J, drift = np.zeros((6, 7)), np.zeros(6)
    path, prev = 0.0, None
    for k in range(300):
        qpos[:] = robot.q0 + rng.normal(scale=0.3, size=7)
        _kinematics(robot, data, qpos, np.zeros(7))
        if not in_place:
            memory.sync()
        code = sk.episode_step(memory.mem, J, drift, k, sk.MEASURE)
        tx, ty, tz = data.oMf[robot.tcp_frame_id].translation.tolist()
        if prev is not None:
            path += math.sqrt((tx - prev[0]) ** 2 + (ty - prev[1]) ** 2 + (tz - prev[2]) ** 2)
        prev = (tx, ty, tz)
        gx, gy, gz = scenario.goal_at(k * episode.dt).tolist()
        distance = math.sqrt((tx - gx) ** 2 + (ty - gy) ** 2 + (tz - gz) ** 2)
        assert memory.path_length == path and memory.distance == distance
        assert np.array_equal(memory.goal(), scenario.goal_at(k * episode.dt))
        assert np.array_equal(episode.q_history[k], qpos)
        assert memory.axis == data.oMf[robot.tcp_frame_id].rotation[:, 2].tolist()
        assert code == (sk.STOP if distance <= episode.loop.stop_radius else sk.GO_ON)


def test_control_phase_gives_the_controllers_accelerations(robot):
    from amex.control.state import RobotState

    memory, episode, data = _memory(robot)
    rng = np.random.default_rng(4)
    mjd = episode.sim.data
    mjd.qpos[:] = robot.q0 + rng.normal(scale=0.2, size=7)
    mjd.qvel[:] = rng.normal(size=7)
    state = RobotState(robot, data, mjd.qpos.copy(), mjd.qvel.copy())
    command = Command(y=state.y + 0.01, yd=np.full(6, 0.1))
    memory.hold(command)
    if memory.collision_on:
        episode.collision.update(data)
    assert sk.episode_step(memory.mem, state.J, state.acc_drift, 0, sk.CONTROL) == sk.GO_ON
    got = memory.x.copy()  # (the controller's own work space, which its oracle overwrites)
    assert np.array_equal(got, episode.osc.accelerations(state, command))
    mujoco.mj_forward(episode.sim.model, mjd)  # the simulator untouched by a dynamic CONTROL phase
    assert np.array_equal(mjd.qpos, state.q)
