"""What the loop of one episode works with, and the checks of its outer steps.

:class:`Episode` is built before an episode's first step (its simulator, controller, sensor and
metrics trace) and turns the last step into the episode's row; :func:`observe`,
:func:`method_step` and :func:`check_simulation` are the outer step's calls. The loop itself is
:func:`amex.sim.episode.run_episode` (and its oracle, :mod:`amex.sim.episode_reference`).
"""

from __future__ import annotations

import math
import time
from typing import Protocol

import mujoco
import numpy as np

from amex.control.collision import CollisionModel
from amex.control.disturbance import DisturbanceConfig, make_inner_controller
from amex.control.osc import Command, OperationalSpaceController, OSCGains
from amex.core.errors import AmexError, SimulationError, stop_behind
from amex.core.types import command_problem
from amex.methods.base import Method, Observation
from amex.robot import RobotModel
from amex.sim.loop import LoopConfig, Trace, authors_samples
from amex.sim.metrics import (
    SUCCESS_005_RADIUS,
    EpisodeResult,
    axis_error,
    paper_sum_sq_acc,
    plan_fidelity,
)
from amex.sim.perception import GoalSensor, PerceptionConfig, PredictionConfig
from amex.sim.scenario import Scenario
from amex.sim.simulation import MismatchConfig, Simulation


class Probe(Protocol):
    """Sees the simulator at the start of every inner step (benchmarks; never in a run)."""

    def __call__(self, k: int, data: mujoco.MjData) -> None:
        """Called before inner step ``k`` reads the state from ``data``."""



class Episode:
    """What the loop of one episode works with, built before its first step."""

    def __init__(
        self,
        robot: RobotModel,
        method: Method,
        scenario: Scenario,
        gains: OSCGains,
        loop: LoopConfig,
        perception: PerceptionConfig | None,
        prediction: PredictionConfig | None,
        mismatch: MismatchConfig | None,
        disturbance: DisturbanceConfig | None,
        reference_path: np.ndarray | None = None,
    ) -> None:
        self.robot, self.method, self.scenario, self.loop = robot, method, scenario, loop
        self.sim = Simulation(robot, scenario, loop.inner_hz, mismatch)
        perception = perception or PerceptionConfig()
        prediction = prediction or PredictionConfig()
        self.sensor = None
        if not perception.exact or prediction.enabled:
            noise_rng = np.random.default_rng(
                np.random.SeedSequence([scenario.seed, scenario.task, scenario.env, 1])
            )
            self.sensor = GoalSensor(scenario.goal_at, perception, prediction, noise_rng)
        n = scenario.n_obstacles
        self.collision = CollisionModel(robot, scenario.obstacle_radii) if n else None
        self.osc = OperationalSpaceController(robot, gains, self.collision)
        self.dt = 1.0 / loop.inner_hz
        self.n_steps = int(math.floor(loop.max_time * loop.inner_hz + 1e-9))
        # the dynamic step's controller: the OSC itself, or the OSC with disturbance compensation
        # (a kinematic simulation has no dynamics to compensate: it never uses one)
        compensation = None if loop.kinematic else disturbance
        self.inner = make_inner_controller(self.osc, self.dt, compensation)
        self.q_history = np.empty((self.n_steps + 1, robot.nv))  # joint angles of every step
        self.trace = Trace()
        self.compute_times = self.trace.compute_times
        self.reference_path = reference_path

    def result(
        self, k: int, t: float, distance: float, sum_sq_acc: float, collided: bool, failure: str
    ) -> EpisodeResult:
        """The episode's row, after its last step ``k`` at time ``t``."""
        scenario, loop, compute_times = self.scenario, self.loop, self.compute_times
        steps = self.q_history[: k + 1]
        trace = self.trace
        cpu = trace.cpu_times
        period = 1.0 / loop.outer_hz
        goal_end = scenario.goal_at(t)
        final_time = float(t)
        if loop.final_time == "samples":  # the authors' count (amex.sim.loop.authors_samples)
            samples = authors_samples(
                k, k == self.n_steps, self.method.finished, loop.max_time, self.dt
            )
            final_time = samples * self.dt
        stops = getattr(self.method, "early_stops", None)  # a method with a time budget
        budget_stops = stops / len(cpu) if isinstance(stops, int) and cpu else math.nan
        fidelity = math.nan
        if self.reference_path is not None and len(trace.tcp):
            fidelity = plan_fidelity(np.array(trace.tcp), self.reference_path, goal_end)
        return EpisodeResult(
            task=scenario.task,
            method=self.method.name,
            env=scenario.env,
            seed=scenario.seed,
            success=bool(distance <= loop.success_radius) and not failure,
            success_005=bool(distance <= SUCCESS_005_RADIUS) and not failure,
            collided=collided,
            final_distance=float(distance),
            final_time=final_time,
            sum_sq_acc=float(sum_sq_acc),
            compute_time_median=float(np.median(compute_times)) if compute_times else math.nan,
            compute_time_mean=float(np.mean(compute_times)) if compute_times else math.nan,
            failure=failure,
            sum_sq_acc_paper=(
                paper_sum_sq_acc(steps, self.dt) if np.isfinite(steps).all() else math.nan
            ),
            int_sq_acc=float(sum_sq_acc) * self.dt,
            compute_cpu_median=float(np.median(cpu)) if cpu else math.nan,
            compute_cpu_mean=float(np.mean(cpu)) if cpu else math.nan,
            deadline_misses=float(np.mean(np.asarray(cpu) > period)) if cpu else math.nan,
            min_clearance=trace.clearance if scenario.n_obstacles else math.nan,
            final_axis_error=axis_error(trace.axis, scenario.goal_axis),
            path_length=trace.path_length,
            plan_fidelity=fidelity,
            compute_cpu_p95=float(np.percentile(cpu, 95)) if cpu else math.nan,
            compute_cpu_max=float(np.max(cpu)) if cpu else math.nan,
            budget_stops=budget_stops,
        )


def observe(
    t: float,
    q: np.ndarray,
    v: np.ndarray,
    y: np.ndarray,
    yd: np.ndarray,
    goal: np.ndarray,
    obstacles: np.ndarray,
    radii: np.ndarray,
) -> Observation:
    """The outer step's :class:`Observation`, its finiteness checked by one sum of squares.

    Time, obstacles and radii are finite by construction (the scenario's motions). Where the sum
    of squares of the other fields is not finite (a NaN, an infinity, or values too large to
    square), the observation is built with its own checks, which raise the same
    :class:`~amex.core.errors.InputError` naming the field as before, or pass huge finite values.
    """
    if math.isfinite(
        float(q @ q) + float(v @ v) + float(y @ y) + float(yd @ yd) + float(goal @ goal)
    ):
        return Observation.prechecked(t, q, v, y, yd, goal, obstacles, radii)
    return Observation(t, q, v, y, yd, goal, obstacles, radii)


def method_step(
    method: Method, obs: Observation, first: bool, trace: Trace, n_joints: int
) -> Command:
    """The method's outer step (reset first at t = 0), timed (wall and thread CPU); checked.

    A malformed answer, or any exception of a method other than ours (a plugin: an
    ``Exception`` or ``SystemExit``), ends the episode as a :class:`SimulationError` whose reason
    says what the method did; an :class:`AmexError` (a failed solve) passes on as such.
    """
    try:
        if first:
            method.reset(obs)
        tic, cpu = time.perf_counter_ns(), time.thread_time_ns()
        command = method.step(obs)
        trace.cpu_times.append((time.thread_time_ns() - cpu) * 1e-9)
        trace.compute_times.append((time.perf_counter_ns() - tic) * 1e-9)
    except AmexError:
        raise
    except (Exception, SystemExit) as error:
        stop = stop_behind(error) if isinstance(error, SystemError) else None
        if stop is not None:  # a stop signal that landed in a compiled call: the run's to handle
            raise stop from None
        text = f"{type(error).__name__}: {error}".strip()[:300]
        raise SimulationError(f"method: {text}", text) from error
    if method.finished:
        return command
    problem = command_problem(command, n_joints)
    if problem:
        raise SimulationError(f"bad_command: {problem}", problem)
    check_command(command)
    return command


def check_command(command: Command) -> None:
    """A :class:`SimulationError` where a part of ``command`` is not finite.

    One sum of squares first (the common, finite command); where it is not finite (a NaN, an
    infinity or values too large to square) the parts are checked one by one.
    """
    squares = 0.0
    for part in command:
        if part is not None:
            squares += float(part @ part)
    if math.isfinite(squares):
        return
    for part in command:
        if part is not None and not np.isfinite(part).all():
            raise SimulationError("nan_command", "the method returned a non-finite command")


def check_simulation(data: mujoco.MjData, speed_limit: np.ndarray) -> None:
    """One comparison per step: a NaN fails ``<=`` as surely as a speed beyond the limit."""
    v = data.qvel
    if not (np.abs(v) <= speed_limit).all():
        if not np.isfinite(v).all():
            raise SimulationError("nan", "non-finite joint state")
        raise SimulationError("diverged", "joint speed beyond the divergence limit")
