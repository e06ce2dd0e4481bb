import mujoco
import numpy as np
import pinocchio as pin
import pytest

from amex.control.collision import CollisionModel
from amex.control.kernels import clip_inplace
from amex.control.osc import PD, Command, OperationalSpaceController, OSCGains, solve_objective
from amex.control.packing import pack_params, params_dtype
from amex.control.state import RobotState
from amex.control.tasks import AxisMap, CollisionMap, PositionMap
from amex.core.errors import SolverError

EPS = 1e-6


def _state(robot, q, v=None):
    v = np.zeros(7) if v is None else v
    return RobotState(robot, robot.model.createData(), q, v)


def _fd_jacobian(robot, f, q):
    cols = []
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = EPS
        cols.append(
            (f(pin.integrate(robot.model, q, dq)) - f(pin.integrate(robot.model, q, -dq)))
            / (2 * EPS)
        )
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("task_map", [PositionMap(), AxisMap()], ids=["pos", "dir"])
def test_task_jacobian_matches_finite_differences(robot, seed, task_map):
    rng = np.random.default_rng(seed)
    q = robot.q0 + rng.normal(scale=0.3, size=7)
    J = task_map.evaluate(_state(robot, q)).J
    J_fd = _fd_jacobian(robot, lambda x: task_map.evaluate(_state(robot, x)).phi.copy(), q)
    assert np.abs(J - J_fd).max() < 1e-5


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("task_map", [PositionMap(), AxisMap()], ids=["pos", "dir"])
def test_task_drift_is_the_time_derivative_of_jacobian_times_velocity(robot, seed, task_map):
    rng = np.random.default_rng(seed)
    q = robot.q0 + rng.normal(scale=0.3, size=7)
    v = rng.normal(size=7)
    drift = task_map.evaluate(_state(robot, q, v)).drift
    h = 1e-6
    # along q(t) = q + t v (zero joint acceleration): phi_ddot = J_dot v
    plus = task_map.evaluate(_state(robot, pin.integrate(robot.model, q, h * v), v)).phid
    minus = task_map.evaluate(_state(robot, pin.integrate(robot.model, q, -h * v), v)).phid
    assert np.abs(drift - (plus - minus) / (2 * h)).max() < 1e-5


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_collision_jacobian_matches_finite_differences(robot, seed):
    rng = np.random.default_rng(seed)
    q = robot.q0 + rng.normal(scale=0.2, size=7)
    tcp = robot.tcp_pose(q).translation
    collision = CollisionModel(robot, [0.02])
    # obstacle just below the hand, inside the margin of the fingers / hand capsule
    collision.set_obstacles((tcp + np.array([0.0, 0.0, -0.045 - 0.01 * seed]))[None])
    cmap = CollisionMap(collision, margin=0.05)
    terms = cmap.evaluate(_state(robot, q))
    assert terms.phi[0] > 0
    J_fd = _fd_jacobian(robot, lambda x: cmap.evaluate(_state(robot, x)).phi.copy(), q)
    assert np.abs(terms.J - J_fd).max() < 1e-5


ORIGINAL = {"reg": 1e-3, "metric": "original", "drift": False, "joint_only": True}


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("kind", ["task", "joint", "both", "none"])
@pytest.mark.parametrize("near", [True, False], ids=["in_margin", "clear"])
@pytest.mark.parametrize("options", [{}, ORIGINAL], ids=["ours", "original"])
def test_compiled_objective_equals_task_by_task_objective(robot, seed, kind, near, options):
    rng = np.random.default_rng(seed)
    collision = CollisionModel(robot, [0.02])
    q = robot.q0 + rng.normal(scale=0.2, size=7)
    tcp = robot.tcp_pose(q).translation
    collision.set_obstacles((tcp + np.array([0.0, 0.0, -0.05 if near else -0.5]))[None])
    gains = OSCGains(damping=PD(3.0, 10.0, 0.01), **options)  # a posture stiffness too
    osc = OperationalSpaceController(robot, gains, collision)
    state = _state(robot, q, rng.normal(size=7))
    task = kind in ("task", "both")
    joint = kind in ("joint", "both")
    command = Command(
        y=state.y + rng.normal(scale=0.01, size=6) if task else None,
        yd=rng.normal(size=6) if task else None,
        q=q + 0.1 if joint else None,
        qd=rng.normal(size=7) if joint else None,
    )
    assert (osc.col_map.evaluate(state).phi[0] > 0) == near
    fast = osc.build_objective(state, command)
    slow = osc.build_objective_reference(state, command)
    assert np.allclose(fast.A, slow.A, rtol=1e-12, atol=1e-10)
    assert np.allclose(fast.b, slow.b, rtol=1e-12, atol=1e-10)
    qdd = osc.accelerations(state, command)  # compiled Cholesky against LAPACK
    assert np.allclose(qdd, solve_objective(slow), rtol=1e-9, atol=1e-9)


def test_the_original_controller_options_change_what_they_say(robot):
    rng = np.random.default_rng(4)
    collision = CollisionModel(robot, [0.02])
    q = robot.q0 + rng.normal(scale=0.2, size=7)
    collision.set_obstacles((robot.tcp_pose(q).translation + [0.0, 0.0, -0.05])[None])
    state = _state(robot, q, rng.normal(size=7))
    joint = Command(q=q + 0.1, qd=np.zeros(7))
    task = Command(y=state.y, yd=np.zeros(6))
    base = OperationalSpaceController(robot, OSCGains(reg=1e-3), collision)
    metric = OperationalSpaceController(robot, OSCGains(reg=1e-3, metric="original"), collision)
    h = np.sqrt(np.arange(7, 0, -1.0))  # diag(sqrt 7, ..., 1)
    diff = metric.build_objective(state, task).A - base.build_objective(state, task).A
    np.testing.assert_allclose(diff, np.diag(1e-3 * (h - 1.0)), atol=1e-15)
    alone = OperationalSpaceController(robot, OSCGains(joint_only=True), collision)
    objective = alone.build_objective(state, joint)  # the joint task alone: A = (reg + c) I
    np.testing.assert_allclose(objective.A, (1e-6 + 1.0) * np.eye(7), atol=1e-15)
    assert not np.allclose(alone.build_objective(state, task).A, np.eye(7))  # tasks unaffected
    no_drift = OperationalSpaceController(robot, OSCGains(drift=False), collision)
    shift = no_drift.build_objective(state, task).b - base.build_objective(state, task).b
    assert np.abs(shift).max() > 1e-6  # the drift of a moving arm is not zero


def test_a_nan_state_is_a_solver_error_carrying_the_system(robot):
    osc = OperationalSpaceController(robot, OSCGains())
    state = _state(robot, np.full(7, np.nan))  # NaN Jacobian: A is not SPD
    with pytest.raises(SolverError, match="not positive definite") as info:
        osc.torque(state, Command(y=np.zeros(6), yd=np.zeros(6)))
    assert info.value.problem.A.shape == (7, 7)


def test_kernel_params_name_every_gain_of_the_controller():
    pos, dir_, joint, col, damping = (PD(1.0 + i, 10.0 + i, 0.1 + i) for i in range(5))
    hdiag, q_rest = np.arange(1.0, 8.0), -np.arange(7.0)
    p = pack_params(pos, dir_, joint, col, damping, False, hdiag, q_rest).view(params_dtype(7))[0]
    for prefix, pd in (("pos", pos), ("axis", dir_), ("joint", joint), ("col", col)):
        named = (p[f"{prefix}_kp"], p[f"{prefix}_kd"], p[f"{prefix}_weight"])
        assert named == (pd.kp, pd.kd, pd.weight)
    assert p["damping_velocity"] == -damping.weight * damping.kd
    assert p["damping_posture"] == damping.weight * damping.kp
    assert not p["drift"]
    assert np.array_equal(p["hdiag"], hdiag) and np.array_equal(p["q_rest"], q_rest)


def test_the_controller_keeps_its_rest_posture_read_only(robot):
    q_rest = robot.q0 + 0.1
    osc = OperationalSpaceController(robot, OSCGains(), q_rest=q_rest)
    q_rest[0] = 5.0  # the caller's array is copied
    assert osc.q_rest[0] == robot.q0[0] + 0.1
    with pytest.raises(ValueError, match="read-only"):
        osc.q_rest[0] = 1.0


def test_compiled_clip_matches_numpy_and_keeps_nan():
    rng = np.random.default_rng(0)
    lo, hi = -np.arange(1.0, 8.0), np.arange(1.0, 8.0)
    x = rng.normal(scale=6.0, size=7)
    x[3] = np.nan
    expected = np.minimum(np.maximum(x, lo), hi)
    clip_inplace(x, lo, hi)
    assert np.array_equal(x, expected, equal_nan=True)


def test_at_rest_on_target_the_controller_only_compensates_gravity(robot):
    osc = OperationalSpaceController(robot, OSCGains())
    state = _state(robot, robot.q0.copy())
    command = Command(y=state.y.copy(), yd=np.zeros(6))
    assert np.abs(osc.accelerations(state, command)).max() < 1e-9
    tau = osc.torque(state, command)
    assert np.allclose(tau, state.bias_forces(), atol=1e-9)


def test_controller_drives_tcp_to_a_nearby_target_in_mujoco(robot):
    gains = OSCGains(pos=PD(400.0, 40.0, 1.0), dir=PD(400.0, 40.0, 0.5))
    osc = OperationalSpaceController(robot, gains)
    model = robot.build_mujoco(0)
    data = mujoco.MjData(model)
    data.qpos[:] = robot.q0
    pdata = robot.model.createData()
    target = robot.task_position(robot.q0)
    target[:3] += [0.05, -0.04, 0.03]
    errors = []
    for _ in range(1500):
        state = RobotState(robot, pdata, data.qpos.copy(), data.qvel.copy())
        errors.append(np.linalg.norm(state.tcp_pos - target[:3]))
        data.qfrc_applied[:] = osc.torque(state, Command(y=target, yd=np.zeros(6)))
        mujoco.mj_step(model, data)
    assert errors[500] < errors[0] and errors[-1] < 1e-3


def test_torques_are_clipped_to_the_limits(robot):
    osc = OperationalSpaceController(robot, OSCGains(pos=PD(1e6, 0.0, 1.0)))
    state = _state(robot, robot.q0.copy())
    target = state.y.copy()
    target[:3] += 0.5
    tau = osc.torque(state, Command(y=target))
    assert np.all(np.abs(tau) <= robot.torque_limit + 1e-12)
    assert np.any(np.isclose(np.abs(tau), robot.torque_limit))
