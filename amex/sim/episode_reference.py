"""The episode loop in Python and numpy, step by step: the oracle of the compiled loop (tests).

:func:`run_reference` is the loop of :func:`amex.sim.episode.run_episode` as it was before its
arithmetic moved into one compiled call per step (:mod:`amex.sim.step_kernel`): a
:class:`~amex.control.state.RobotState` at every step, the TCP path's length and the stop rule's
distance in Python floats, the controller's own calls. The tests run both on the same episodes
and require every result to be equal, bit for bit. Never used by a run.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from amex.control.osc import Command
from amex.control.state import RobotState
from amex.core.compiled import kernel
from amex.core.errors import AmexError, SimulationError, WriteError
from amex.sim.episode_setup import Episode, Probe, check_simulation, method_step, observe
from amex.sim.loop import Recorder, StepRecord
from amex.sim.metrics import EpisodeResult


def run_reference(
    e: Episode, recorder: Recorder | None = None, probe: Probe | None = None
) -> EpisodeResult:
    """The two-rate loop of :func:`amex.sim.episode._run` in Python and numpy (the oracle)."""
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
    goal = scenario.goal_at(0.0)
    gx, gy, gz = goal.tolist()
    goal_moves_until = scenario.goal_stop_time if np.any(scenario.goal_velocity) else -1.0
    kinematic = loop.kinematic
    detect_contacts = kinematic and scenario.n_obstacles > 0
    no_torque = np.zeros(robot.nv)  # what a kinematic step logs as its torque
    q_history = e.q_history
    lag = loop.state_lag
    seen_tcp: list[float] | None = None  # the lagging TCP position of the stop rule
    seen_y: np.ndarray | None = None  # the lagging task state methods see
    seen_yd: np.ndarray | None = None
    sum_sq_acc = 0.0
    collided = False
    failure = ""
    command = Command()
    distance = math.inf
    t = 0.0
    k = 0
    trace = e.trace
    tcp_prev = None
    state: RobotState | None = None
    try:
        for k in range(n_steps + 1):
            if probe is not None:
                probe(k, mjd)
            t = k * dt
            outer = k % substeps == 0
            # copies on outer steps (observations and logs keep them), views otherwise
            q = qpos.copy() if outer else qpos
            v = qvel.copy() if outer else qvel
            state = RobotState(robot, pdata, q, v)
            q_history[k] = q
            tx, ty, tz = tcp = state.y_list[:3]
            if tcp_prev is not None:  # the TCP path's length, step by step
                trace.path_length += math.sqrt(
                    (tx - tcp_prev[0]) ** 2 + (ty - tcp_prev[1]) ** 2 + (tz - tcp_prev[2]) ** 2
                )
            tcp_prev = tcp
            if t <= goal_moves_until:
                goal = scenario.goal_at(t)
                gx, gy, gz = goal.tolist()
            px, py, pz = state.y_list[:3] if seen_tcp is None else seen_tcp
            distance = math.sqrt((px - gx) ** 2 + (py - gy) ** 2 + (pz - gz) ** 2)
            if distance <= loop.stop_radius:
                break
            if k == n_steps:
                break
            if moving_obstacles:
                obstacles = scenario.obstacles_at(t)
                sim.set_obstacles(obstacles)
                if collision is not None:
                    collision.set_obstacles(obstacles)
            if outer:
                trace.outer(state, collision, pdata)
                seen = goal if sensor is None else sensor.measure(t)
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
            if lag:  # what the next step's stop rule and observation see
                seen_tcp = state.y_list[:3]
                if (k + 1) % substeps == 0:
                    seen_y, seen_yd = state.y, state.yd
            if kinematic:
                qacc = osc.accelerations(state, command)
                tau = no_torque
                kernel("amex.control.kernels", "euler_inplace")(qpos, qvel, qacc, dt)
                mjd.time += dt
                if detect_contacts:
                    mujoco.mj_kinematics(mjm, mjd)
                    mujoco.mj_collision(mjm, mjd)
            else:
                if plain:
                    tau = osc.torque_into(state, command, qfrc)
                else:
                    tau = inner.torque(state, command)
                    qfrc[:] = tau
                mj_step(mjm, mjd)
                qacc = mjd.qacc
            sum_sq_acc += float(qacc.dot(qacc))  # (the same BLAS ddot as qacc @ qacc)
            if mjd.ncon:
                collided = True
            if outer:  # NaNs persist, so checking at the outer rate loses nothing
                check_simulation(mjd, speed_limit)
                if recorder is not None:
                    internals = method.internals()
                    recorder.record(StepRecord(t, state, obs, command, internals, tau, qacc))
    except SimulationError as error:
        failure = error.reason
    except WriteError:
        raise  # a record could not be written (a full disk): the run stops, the episode is redone
    except AmexError as error:
        failure = f"solver: {error}"
    if state is not None:
        trace.axis = state.y_list[3:6]
    return e.result(k, t, distance, sum_sq_acc, collided, failure)
