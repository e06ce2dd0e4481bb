"""One episode: the two-rate loop of the paper's Fig. 3 in MuJoCo.

Outer loop (``outer_hz``, 100 Hz): the method turns an :class:`~amex.core.types.Observation` into a
:class:`~amex.core.types.Command`; inner loop (``inner_hz``, 1 kHz): the operational-space
controller (Eq. 4-6) turns the held command into torques ``tau = M q_ddot* + h`` and MuJoCo
integrates one step (``sim=dynamic``), or ``q_ddot*`` is integrated by explicit Euler
(``sim=kinematic``, as the authors' harness). The episode stops within ``stop_radius`` of the
current goal or at ``max_time``; success is judged at ``success_radius``. Numerical trouble, a
failed solve or a malformed answer of the method end the episode with a recorded ``failure``.
The loop, the two radii, the state lag and the kinematic simulation: ``docs/simulation.md``.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from amex.control.disturbance import DisturbanceConfig
from amex.control.osc import Command, OSCGains
from amex.control.state import RobotState
from amex.core.compiled import kernel
from amex.core.errors import AmexError, SimulationError, WriteError
from amex.methods.base import Method
from amex.robot import RobotModel
from amex.sim.episode_reference import run_reference
from amex.sim.episode_setup import Episode, Probe, check_simulation, method_step, observe
from amex.sim.inner_step import StepMemory
from amex.sim.loop import LoopConfig, Recorder, StepRecord
from amex.sim.metrics import EpisodeResult
from amex.sim.perception import PerceptionConfig, PredictionConfig
from amex.sim.scenario import Scenario
from amex.sim.simulation import MismatchConfig
from amex.sim.step_layout import BOTH, CONTROL, MEASURE, STOP

_LWA = pin.LOCAL_WORLD_ALIGNED
#: A :class:`StepRecord` made from its fields' tuple without the named tuple's Python
#: ``__new__`` (0.25 against 0.52 us an outer step of a recorded episode, 2026-12-07)
_record = tuple.__new__


def run_episode(
    robot: RobotModel,
    method: Method,
    scenario: Scenario,
    gains: OSCGains,
    loop: LoopConfig,
    recorder: Recorder | None = None,
    perception: PerceptionConfig | None = None,
    prediction: PredictionConfig | None = None,
    mismatch: MismatchConfig | None = None,
    disturbance: DisturbanceConfig | None = None,
    reference_path: np.ndarray | None = None,
    probe: Probe | None = None,
) -> EpisodeResult:
    """Execute ``method`` in ``scenario`` and measure it (see :mod:`amex.sim.metrics`).

    Args:
        robot: the arm (simulated and controlled with the same model).
        method: a fresh or reusable method instance; :meth:`Method.reset` is called here.
        scenario: the environment (goal and obstacle motions).
        gains: inner-controller gains, including the method's task gains.
        loop: rates and stopping rules.
        recorder: optional per-step observer (logs).
        perception: goal noise and latency seen by the method (default: exact).
        prediction: Kalman prediction of the perceived goal (default: off).
        mismatch: how the simulated arm differs from the controller's model (default: none).
        disturbance: compensation of unmodelled torques in the inner controller (default: none,
            the paper's controller); see :mod:`amex.control.disturbance`.
        reference_path: the reference plan's TCP positions, shape (N + 1, 3) [m], for
            ``plan_fidelity`` (NaN without it).
        probe: called as ``probe(k, data)`` at the start of every inner step ``k``, with the
            simulator's ``MjData`` (``amex.app.bench_inner`` times the steps with it); None in runs.
    """
    episode = Episode(
        robot,
        method,
        scenario,
        gains,
        loop,
        perception,
        prediction,
        mismatch,
        disturbance,
        reference_path,
    )
    # The compiled step moves the goal by Scenario's own closed form; a scenario of another kind
    # (the live page's, whose goal a hand moves) runs the Python loop, which asks its goal_at.
    if type(scenario) is Scenario:
        result = _run(episode, recorder, probe)
    else:
        result = run_reference(episode, recorder, probe)
    if recorder is not None:
        recorder.finish(result)
    return result


def _run(e: Episode, recorder: Recorder | None, probe: Probe | None = None) -> EpisodeResult:
    """The two-rate loop (module notes), one function: its locals are the 1 kHz loop's state.

    Two kinds of step. An inner step of the plain controller (no disturbance compensation) makes
    the library calls the step needs (Pinocchio's kinematics and inverse dynamics, coal's
    distances, ``mj_step``) and two compiled calls: :func:`~amex.sim.step_kernel.episode_step`
    (the history, path length, goal and stop rule, the collision task and the OSC solve) and
    :func:`~amex.sim.step_kernel.clip_torque`. Every other step (the outer steps, the step
    before one under ``state_lag``, every step with disturbance compensation) builds a
    :class:`RobotState`, whose quantities the methods, the recorder and the compensation read,
    and runs the same compiled phases around the method's step. Both give the numbers of
    :func:`amex.sim.episode_reference.run_reference`, the loop in Python, bit for bit.

    Longer than 80 lines on purpose: splitting the inner step into calls would cost attribute
    look-ups and calls at every one of up to 10,000 steps an episode.
    """
    robot, method, scenario, loop = e.robot, e.method, e.scenario, e.loop
    sim, sensor, collision, osc, inner = e.sim, e.sensor, e.collision, e.osc, e.inner
    pdata = robot.model.createData()
    mjm, mjd = sim.model, sim.data
    qpos, qvel, qfrc, mj_step = mjd.qpos, mjd.qvel, mjd.qfrc_applied, mujoco.mj_step
    plain = inner is osc  # no disturbance compensation: the torque goes straight into MuJoCo
    substeps, dt, n_steps = loop.substeps, e.dt, e.n_steps
    speed_limit = loop.speed_limit_factor * robot.velocity_limit
    goal_axis = scenario.goal_axis
    radii = scenario.obstacle_radii
    moving_obstacles = bool(scenario.n_obstacles) and bool(np.any(scenario.obstacle_velocity))
    obstacles = scenario.obstacles_at(0.0)
    if collision is not None:
        collision.set_obstacles(obstacles)
    kinematic = loop.kinematic
    detect_contacts = kinematic and scenario.n_obstacles > 0
    no_torque = np.zeros(robot.nv)  # what a kinematic step logs as its torque
    memory = StepMemory(
        robot, pdata, osc, collision, scenario, loop, dt, e.q_history, qpos, qvel, qfrc
    )
    mem, x, zero_copy = memory.mem, memory.x, memory.zero_copy
    compiled = plain or kinematic  # the compiled CONTROL phase (else the compensation's torque)
    step = kernel("amex.sim.step_kernel", "episode_step")
    clip = kernel("amex.sim.step_kernel", "clip_torque")
    speeds_ok = kernel("amex.sim.step_kernel", "speeds_within_limit")
    model, fid, zero_acc = robot.model, robot.tcp_frame_id, robot.zero_velocity
    fk, jacobians, rnea = pin.forwardKinematics, pin.computeJointJacobians, pin.rnea
    place, frame_jacobian = pin.updateFramePlacement, pin.getFrameJacobian
    frame_acc = pin.getFrameClassicalAcceleration
    distances = collision is not None and collision.zero_copy
    if collision is not None:
        gm, gd = collision.geom_model, collision.geom_data
    place_geometry, compute_distances = pin.updateGeometryPlacements, pin.computeDistances
    qacc_sim = mjd.qacc
    lag = loop.state_lag
    seen_y: np.ndarray | None = None  # the lagging task state methods see
    seen_yd: np.ndarray | None = None
    sum_sq_acc = 0.0
    collided = False
    failure = ""
    command = Command()
    col_on = False  # the held command tracks the collision task
    k = 0
    trace = e.trace
    try:
        for k in range(n_steps + 1):
            if probe is not None:
                probe(k, mjd)
            outer = k % substeps == 0
            if compiled and not outer and not (lag and (k + 1) % substeps == 0):
                # an inner step: the library calls and two compiled calls (docstring)
                fk(model, pdata, qpos, qvel, zero_acc)
                jacobians(model, pdata)
                place(model, pdata, fid)
                J = frame_jacobian(model, pdata, fid, _LWA)
                drift = frame_acc(model, pdata, fid, _LWA).vector
                if not zero_copy:
                    memory.sync()
                if moving_obstacles:
                    obstacles = scenario.obstacles_at(k * dt)
                    sim.set_obstacles(obstacles)
                    if collision is not None:
                        collision.set_obstacles(obstacles)
                if col_on:  # coal's results, read in place by the step (CollisionModel.update)
                    if distances:
                        place_geometry(model, pdata, gm, gd)
                        compute_distances(gm, gd)
                    else:
                        collision.update(pdata)  # type: ignore[union-attr]
                code = step(mem, J, drift, k, BOTH)
                if code:
                    if code == STOP:
                        break
                    raise osc.solver_error(memory.info)
                if kinematic:
                    qacc = x
                    mjd.time += dt
                    if detect_contacts:
                        mujoco.mj_kinematics(mjm, mjd)
                        mujoco.mj_collision(mjm, mjd)
                else:
                    clip(mem, rnea(model, pdata, qpos, qvel, x))
                    mj_step(mjm, mjd)
                    qacc = qacc_sim
                sum_sq_acc += float(qacc.dot(qacc))  # (the same BLAS ddot as qacc @ qacc)
                if mjd.ncon:
                    collided = True
                continue
            t = k * dt
            # copies on outer steps (observations and logs keep them), views otherwise
            q = qpos.copy() if outer else qpos
            v = qvel.copy() if outer else qvel
            state = RobotState(robot, pdata, q, v)
            if not zero_copy:
                memory.sync()
            if step(mem, state.J, state.acc_drift, k, MEASURE) == STOP:
                break
            if moving_obstacles:
                obstacles = scenario.obstacles_at(t)
                sim.set_obstacles(obstacles)
                if collision is not None:
                    collision.set_obstacles(obstacles)
            if outer:
                trace.outer(state, collision, pdata)  # (coal's distances for this state)
                seen = memory.goal() if sensor is None else sensor.measure(t)
                obs = observe(
                    t,
                    q,
                    v,
                    state.y if seen_y is None else seen_y,
                    state.yd if seen_yd is None else seen_yd,
                    np.concatenate([seen, goal_axis]),
                    obstacles,
                    radii,
                )
                command = method_step(method, obs, k == 0, trace, robot.nv)
                if method.finished:  # the method ended the execution (the authors' CR)
                    break
                if compiled and command is not memory.command:
                    memory.hold(command)
                    col_on = memory.collision_on
            if lag and (k + 1) % substeps == 0:  # what the next outer step's observation sees
                seen_y, seen_yd = state.y, state.yd
            if compiled:
                if col_on and not outer:
                    collision.update(pdata)  # type: ignore[union-attr]
                if step(mem, state.J, state.acc_drift, k, CONTROL):
                    raise osc.solver_error(memory.info)
                if kinematic:
                    qacc = x.copy() if outer else x
                    tau = no_torque
                    mjd.time += dt
                    if detect_contacts:
                        mujoco.mj_kinematics(mjm, mjd)
                        mujoco.mj_collision(mjm, mjd)
                else:
                    clip(mem, rnea(model, pdata, qpos, qvel, x))
                    tau = qfrc
                    mj_step(mjm, mjd)
                    qacc = qacc_sim
            else:
                tau = inner.torque(state, command)
                qfrc[:] = tau
                mj_step(mjm, mjd)
                qacc = qacc_sim
            sum_sq_acc += float(qacc.dot(qacc))
            if mjd.ncon:
                collided = True
            if outer:  # NaNs persist, so checking at the outer rate loses nothing
                if not speeds_ok(mem):  # (one compiled comparison; the error says which)
                    check_simulation(mjd, speed_limit)
                if recorder is not None:
                    internals = method.internals()
                    recorder.record(
                        _record(StepRecord, (t, state, obs, command, internals, tau, qacc))
                    )
    except SimulationError as error:
        failure = error.reason
    except WriteError:
        raise  # a record could not be written (a full disk): the run stops, the episode is redone
    except AmexError as error:
        failure = f"solver: {error}"
    if memory.measured:
        trace.axis = memory.axis
    trace.path_length = memory.path_length
    return e.result(k, k * dt, memory.distance, sum_sq_acc, collided, failure)
