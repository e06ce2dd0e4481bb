"""Sampling-based MPC (MPPI, Williams et al. 2017) in the arm's joint space, on a time budget.

Every outer step samples ``samples`` joint-acceleration sequences around the nominal one, rolls
each out over ``knots`` intervals of ``knot_dt`` from the measured ``(q, q_dot)`` through a double
integrator, scores it (:mod:`amex.plan.rollouts`: TCP position and axis to the current goal,
CR's collision proxy against the perceived obstacle spheres, joint velocity, acceleration in the
plan's metric, joint limits) and moves the nominal to the cost-weighted mean,
``u <- u + sum_k w_k eps_k`` with ``w_k ~ exp(-(S_k - S_min) / (temperature (S_med - S_min)))``
(the temperature relative to the spread of the costs, so that one value serves far from and
near the goal). The sequences are piecewise linear through control points ``control_every``
knots apart (the noise is drawn at the control points only: temporally correlated, smooth);
the first control point is the acceleration being executed and is never perturbed, so the
commanded acceleration changes continuously. The nominal is the previous solution shifted by
the time elapsed (the reference plan's accelerations at the first step); sample 0 is that
warm start itself. The command is the nominal's motion over the coming period, as CR's:
``q* = q(t + dt/2)``, ``q_dot* = (q(t + dt) - q(t)) / dt``, for the inner controller's joint task.

Time budget: the rollouts run in chunks of ``chunk`` samples; before each chunk the step checks
its own elapsed time (thread CPU time, or wall time) against ``budget`` and stops early when the
next chunk would not fit (the estimate: the median chunk time of the last step plus the median
time after the rollouts of the last nine steps, both kept across episodes), updating from the
samples evaluated so far (none: the warm start is sent as it is). Early stops are counted
(:attr:`MPPI.early_stops`, in :meth:`internals` and as ``budget_stops`` in episodes.csv). A step
the budget cuts short depends on the machine's speed: an episode is reproducible bit for bit
when its ``budget_stops`` is 0, and says so when it is not.

Seeding: the noise of step k is drawn from ``SeedSequence([seed, MPPI_STREAM, k, h(obs)])``,
``h`` a 128-bit digest of the observation, which the episode's seed, task and environment
determine: the same episode gives the same rows in any process, worker or shard, and no global
random state is read. Design and measurements: ``docs/methods/mppi.md``.

Over 400 lines on purpose: like every method, its config, status and class in one module; the
sampler, the budget and the command shaping share the method's state (the rollouts themselves are
amex.plan.rollouts).
"""

from __future__ import annotations

import gc
import hashlib
import math
import struct
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from amex.core.errors import ConfigError
from amex.core.lazy import LazyDict, LazyRows
from amex.core.scaling import scaled
from amex.core.types import Command
from amex.methods.base import Method, MethodConfig, Observation, invalid, require_finite

if TYPE_CHECKING:  # the rollouts need Pinocchio and Numba; imported when an MPPI is built
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

#: Second word of every sampler seed: MPPI's stream, apart from any other user of the seed.
MPPI_STREAM = 0x6D707069  # "mppi"
CLOCKS: dict[str, Callable[[], int]] = {"thread": time.thread_time_ns, "wall": time.perf_counter_ns}
#: ``budget_clock=work``: the deterministic clock, a cost model of one sample's rollout per
#: horizon knot, ``WORK_NS_KNOT + WORK_NS_PAIR * pairs`` [ns] (pairs: arm capsules x obstacles),
#: and of a step's work after its rollouts, ``WORK_NS_TAIL`` [ns]. Calibrated on the 2-core AMD
#: EPYC CI machine, thread CPU, chunks of 32 (Tasks 1, 3, 4; 8-32 knots; 255-500 ns per sample
#: and knot, the model's bound above the measured); docs/methods/mppi.md.
WORK_NS_KNOT = 250
WORK_NS_PAIR = 20
WORK_NS_TAIL = 200_000
BUDGET_CLOCKS = (*CLOCKS, "work")
COMMANDS = ("matched", "midpoint")


@dataclass
class MPPIConfig(MethodConfig):
    """MPPI settings: sampling, horizon, cost weights (:mod:`amex.plan.rollouts`) and budget.

    ``pos`` and ``dir`` (inherited) are unused: MPPI sends joint targets, tracked with the shared
    ``controller.joint`` gains.

    Attributes:
        samples: K, the number of sampled sequences per step (sample 0 is the warm start).
        knots: H, the horizon's knot intervals.
        knot_dt: length of a knot interval [s]; the horizon is ``knots * knot_dt``.
        control_every: knot intervals between control points (the noise's correlation length).
        noise: standard deviation of the acceleration noise at a control point [rad/s^2].
        temperature: the softmax temperature, relative to the costs' median minus their minimum.
        goal_position: running TCP distance to the goal [1/(m s)].
        goal_axis: running TCP z-axis error [1/s].
        final_position: TCP position error at the horizon's end [1/m^2].
        final_axis: TCP z-axis error at the horizon's end [-].
        final_velocity: joint velocity at the horizon's end [s^2/rad^2].
        velocity: running joint velocity [s/rad^2].
        acceleration: joint acceleration in the plan's metric [s^3/rad^2].
        collision: the collision proxy ``max(0, 1 - d / margin)^2`` per pair and second [1/s].
        collision_margin: distance at which the collision proxy starts [m] (original 0.1 m as
            CR's; a length in original units, :mod:`amex.core.scaling`).
        joint_limits: squared excursions beyond the joint and speed limits [1/(rad^2 s)].
        limit_margin: distance inside the joint limits where their cost starts [rad].
        budget: the step's time budget [s], at most the outer period.
        budget_clock: ``thread`` (the thread's CPU time, as ``deadline_misses`` counts it),
            ``wall``, or ``work``: a deterministic clock, the predicted time of the work done
            (:data:`WORK_NS_KNOT`), so that where the budget binds it binds at the same sample
            on every machine and run (bit-reproducible; the deadline then holds on machines as
            fast as the model's).
        chunk: samples per compiled call, the budget's granularity.
        command: ``matched`` (the targets that make the inner joint PD reach the nominal's
            velocity at the end of the period) or ``midpoint`` (CR's: the nominal's state in
            the middle of the period).
        tracking_kp: stiffness of the inner controller's joint task the command is shaped for
            [1/s^2] (conf/method/mppi.yaml: ``controller.joint.kp``).
        tracking_kd: its damping [1/s] (conf/method/mppi.yaml: ``controller.joint.kd``).
        inner_hz: the inner controller's rate [Hz] (conf/method/mppi.yaml: ``inner_hz``).
        seed: first word of the sampler's seeds (conf/method/mppi.yaml: the run's seed).
    """

    name: str = "mppi"
    samples: int = 256  # [-]
    knots: int = 16  # [-]
    knot_dt: float = 0.05  # [s]
    control_every: int = 2  # [knots]
    noise: float = 0.5  # [rad/s^2]
    temperature: float = 0.05  # [-]
    goal_position: float = 100.0  # [1/(m s)]
    goal_axis: float = 10.0  # [1/s]
    final_position: float = 10000.0  # [1/m^2]
    final_axis: float = 400.0  # [-]
    final_velocity: float = 10.0  # [s^2/rad^2]
    velocity: float = 0.1  # [s/rad^2]
    acceleration: float = 1.0  # [s^3/rad^2]
    collision: float = 100.0  # [1/s]
    collision_margin: float = field(default=0.1, metadata=scaled(1))  # [m] original (CR's)
    joint_limits: float = 100.0  # [1/(rad^2 s)]
    limit_margin: float = 0.05  # [rad]
    budget: float = 0.007  # [s]
    budget_clock: str = "thread"
    chunk: int = 32  # [-]
    command: str = "matched"
    tracking_kp: float = 100.0  # [1/s^2]
    tracking_kd: float = 100.0  # [1/s]
    inner_hz: float = 1000.0  # [Hz]
    seed: int = 0

    def validate(self) -> None:
        """Raise :class:`ConfigError` for sampling, horizon or budget settings MPPI cannot use."""
        for key in ("samples", "knots", "control_every", "chunk"):
            value = getattr(self, key)
            if int(value) != value or value < 1:
                raise invalid(key, value, "an integer >= 1")
        if int(self.seed) != self.seed:
            raise invalid("seed", self.seed, "an integer >= 0")
        for key in ("knot_dt", "temperature", "budget", "collision_margin"):
            if not getattr(self, key) > 0.0:
                raise invalid(key, getattr(self, key), "a finite number > 0")
        if self.budget_clock not in BUDGET_CLOCKS:
            raise invalid("budget_clock", self.budget_clock, sorted(BUDGET_CLOCKS))
        if self.command not in COMMANDS:
            raise invalid("command", self.command, list(COMMANDS))
        if not (self.inner_hz > 0.0 and self.tracking_kp + self.tracking_kd > 0.0):
            values = [self.tracking_kp, self.tracking_kd, self.inner_hz]
            valid = "gains >= 0, not both 0, a rate > 0"
            raise invalid("tracking_kp, tracking_kd, inner_hz", values, valid)


class MPPIStatus(NamedTuple):
    """What one MPPI step did.

    Attributes:
        evaluated: samples rolled out (``samples`` unless it stopped early).
        early_stop: whether the budget stopped the rollouts before all samples.
        warm_cost: cost of the warm start (sample 0; nan if not evaluated).
        best_cost: lowest cost of the samples evaluated (nan if none).
        effective_samples: ``1 / sum w_k^2`` of the weights (0 if none).
        elapsed: the step's time on the budget's clock [s].
    """

    evaluated: int
    early_stop: bool
    warm_cost: float
    best_cost: float
    effective_samples: float
    elapsed: float


def interpolation_matrix(knots: int, control_every: int) -> np.ndarray:
    """B, shape (H, M): the held acceleration of interval h from the M control points.

    The acceleration is piecewise linear through control points ``control_every`` intervals
    apart, read at each interval's midpoint; ``M = ceil(H / control_every) + 1``.
    """
    m = -(-knots // control_every) + 1
    x = (np.arange(knots) + 0.5) / control_every  # midpoints, in control intervals
    lo = np.minimum(np.floor(x).astype(int), m - 2)
    frac = x - lo
    B = np.zeros((knots, m))
    B[np.arange(knots), lo] = 1.0 - frac
    B[np.arange(knots), lo + 1] = frac
    return B


def shift_controls(controls: np.ndarray, shift: float) -> np.ndarray:
    """The piecewise-linear sequence through ``controls`` (M, n) read ``shift`` intervals later.

    Beyond the last control point it falls linearly to zero over one interval, then stays zero
    (the warm start coasts where the last solution ends).
    """
    m = len(controls)
    padded = np.vstack([controls, np.zeros((2, controls.shape[1]))])
    x = np.minimum(np.arange(m) + shift, m)
    lo = np.floor(x).astype(int)
    frac = (x - lo)[:, None]
    return (1.0 - frac) * padded[lo] + frac * padded[lo + 1]


def observation_words(obs: Observation) -> list[int]:
    """The 128-bit blake2b digest of every number of ``obs``, as four 32-bit words."""
    h = hashlib.blake2b(struct.pack("<d", obs.t), digest_size=16)
    for part in (obs.q, obs.qd, obs.y, obs.yd, obs.goal, obs.obstacles, obs.obstacle_radii):
        h.update(np.ascontiguousarray(part, dtype="<f8").data)
    return list(struct.unpack("<4I", h.digest()))


def softmax_weights(costs: np.ndarray, temperature: float) -> np.ndarray:
    """MPPI's weights of ``costs`` (S,), summing to 1 (module notes); one-hot when all equal."""
    best = float(costs.min())
    spread = float(np.median(costs)) - best
    if not (math.isfinite(spread) and spread > 0.0):
        weights = np.zeros(len(costs))
        weights[int(np.argmin(costs))] = 1.0
        return weights
    weights = np.exp(-(costs - best) / (temperature * spread))
    return weights / weights.sum()


def pd_period(kp: float, kd: float, h: float, substeps: int) -> tuple[tuple[float, float], float]:
    """The end velocity of a joint PD over one outer period: ``v_end = a_q q + a_v v + b r``.

    ``substeps`` explicit Euler steps of ``h`` of ``q' = v``, ``v' = kp (q* - q) + kd (q_dot* -
    v)`` from ``(q, v)``; ``r = kp q* + kd q_dot*`` is the one combination of the targets the PD
    sees. Returns ``((a_q, a_v), b)``.
    """
    F = np.array([[1.0, h], [-h * kp, 1.0 - h * kd]])
    g = np.array([0.0, h])
    power, total = np.eye(2), np.zeros(2)
    for _ in range(substeps):
        total = F @ total + g
        power = F @ power
    return (float(power[1, 0]), float(power[1, 1])), float(total[1])


class MPPI(Method):
    """Model-predictive path integral control in joint space (see the module notes).

    Args:
        plan: the reference plan; its joint trajectory ``plan.q`` gives the first warm start,
            its metric diag(H) that of the acceleration cost (empty: identity).
        config: MPPI settings (None: :class:`MPPIConfig`'s defaults).
        dt: outer period [s]: the command covers it; the budget may not exceed it.
        robot: the arm (kinematics, capsules, joint limits); required.

    Raises:
        ConfigError: for invalid settings, a budget longer than ``dt``, control points closer
            than ``dt``, a missing robot or a plan without its joints.
    """

    name = "mppi"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = MPPIConfig
    needs_robot = True
    config: MPPIConfig
    robot: RobotModel

    def __init__(
        self,
        plan: ReferencePlan,
        config: MPPIConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        from amex.plan.batch_kinematics import batch_kinematics
        from amex.plan.rollouts import Rollouts, RolloutWeights, rollout_model

        super().__init__(plan, config, dt, robot)
        c, robot = self.config, self.robot
        if c.budget > self.dt:
            raise invalid("budget", c.budget, f"> 0 and <= the outer period {self.dt:g} [s]")
        self.control_dt = float(c.control_every * c.knot_dt)
        if self.control_dt < self.dt:
            raise ConfigError(
                f"invalid method.control_every * knot_dt = {self.control_dt:g} s; valid: >= the "
                f"outer period {self.dt:g} s (the command reads one control interval)"
            )
        metric = np.asarray(plan.metric, dtype=float) if len(plan.metric) else np.ones(robot.nv)
        self.kinematics = batch_kinematics(robot)
        weights = RolloutWeights(
            c.goal_position, c.goal_axis, c.final_position, c.final_axis, c.final_velocity,
            c.velocity, c.acceleration, c.collision, c.collision_margin, c.joint_limits,
            c.limit_margin,
        )  # fmt: skip
        self.B = interpolation_matrix(int(c.knots), int(c.control_every))
        self.rollouts = Rollouts(rollout_model(robot, self.kinematics, metric), weights, self.B)
        self.clock = CLOCKS.get(c.budget_clock, time.thread_time_ns)  # ``work``: for elapsed
        substeps = max(int(round(c.inner_hz * self.dt)), 1)
        kp, kd = float(c.tracking_kp), float(c.tracking_kd)
        self.pd_map = pd_period(kp, kd, 1.0 / c.inner_hz, substeps)
        self.reference_acc = np.gradient(np.gradient(plan.q, plan.dt, axis=0), plan.dt, axis=0)
        self.reference_dt = float(plan.dt)
        self.seed(int(c.seed))
        # the time estimates are the machine's, not the episode's: kept across restarts, so that
        # an episode's first step is budgeted too (from the warm-up's chunks at first)
        self._chunk_time = 0  # [ns] typical duration of a chunk (the next one's estimate)
        self._tails: deque[int] = deque(maxlen=9)  # [ns] the last steps' times after rollouts
        self._tail_time = 0  # [ns] their median, the next step's estimate
        self.restart()
        self._warm_up(robot.q0)

    def _warm_up(self, q0: np.ndarray) -> None:
        """Two untimed steps on a made-up observation, then :meth:`restart`.

        Loads the compiled kernel and lets numpy and the generator take their first-call costs
        here, never in a timed step (where they could stop the first step early); the second
        step's times are the first estimates of the budget.
        """
        tcp = self.kinematics.frame_positions(q0[None], self.robot.tcp_frame_id)[0]
        y = np.concatenate([tcp, [0.0, 0.0, 1.0]])
        obs = Observation(0.0, q0, np.zeros_like(q0), y, np.zeros(6), y + 0.1,
                          tcp[None] + 0.1, np.array([0.05]))  # fmt: skip
        self.sample(obs, budgeted=False)
        self.target(obs.q, obs.qd)
        self.nominal_path()
        self._tails.clear()  # the first call's times are not a step's: measured again
        self.sample(obs, budgeted=False)
        self.restart()

    # ----------------------------------------------------------------------------- state
    def seed(self, *words: int) -> None:
        """Set the sampler's leading seed words (default: ``config.seed``); see the module notes.

        A caller that knows the episode may pass e.g. its ``(seed, task, env)``.
        """
        self._seed_words = [int(w) for w in words]

    def restart(self) -> None:
        """Forget the last solution: the next step warm-starts from the reference plan."""
        m = self.B.shape[1]
        times = np.arange(m) * self.control_dt / self.reference_dt
        index = np.minimum(np.round(times).astype(int), len(self.reference_acc) - 1)
        self.controls = self.reference_acc[index].copy()  # (M, n) [rad/s^2], at t_controls
        self.controls[times > len(self.reference_acc) - 1] = 0.0
        self.t_controls = 0.0
        self.steps_done = 0
        self.early_stops = 0
        self._start = (np.zeros(0), np.zeros(0))
        self._status = MPPIStatus(0, False, math.nan, math.nan, 0.0, 0.0)

    @property
    def status(self) -> MPPIStatus:
        """What the last step did."""
        return self._status

    def rng(self, obs: Observation) -> np.random.Generator:
        """The generator of this step's noise (module notes)."""
        words = [*self._seed_words, MPPI_STREAM, self.steps_done, *observation_words(obs)]
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence(words)))

    def sample(self, obs: Observation, budgeted: bool = True) -> MPPIStatus:
        """Shift the warm start, roll out the samples within the budget, update the nominal.

        ``budgeted=False`` evaluates every sample whatever the time (the warm-up's steps); the
        times are measured all the same.

        Python's cyclic garbage collector is held off during the step (and restored as it was):
        a full collection costs milliseconds of the step's own thread time, at moments that
        depend on the process's history, not on the episode.

        Raises:
            InputError: for a non-finite observation (nothing changed).
        """
        require_finite(
            t=obs.t, q=obs.q, qd=obs.qd, y=obs.y, yd=obs.yd, goal=obs.goal,
            obstacles=obs.obstacles, obstacle_radii=obs.obstacle_radii,
        )  # fmt: skip (before any state changes: a rejected step leaves the method as it was)
        collecting = gc.isenabled()
        gc.disable()
        try:
            return self._sample(obs, budgeted)
        finally:
            if collecting:
                gc.enable()

    def _sample(self, obs: Observation, budgeted: bool) -> MPPIStatus:
        c, clock = self.config, self.clock
        start = clock()
        shift = (obs.t - self.t_controls) / self.control_dt
        if shift != 0.0:
            self.controls = shift_controls(self.controls, shift)
        self.t_controls = float(obs.t)
        self._start = (obs.q.copy(), obs.qd.copy())
        rng, K, n = self.rng(obs), int(c.samples), len(obs.q)
        m = self.B.shape[1]
        eps = np.zeros((K, m, n))
        costs = np.empty(K)
        budget = int(c.budget * 1e9)
        goal_pos, goal_axis = obs.goal[:3], obs.goal[3:6]
        evaluated, early, chunk_times = 0, False, []
        work = c.budget_clock == "work"
        per_sample = int(c.knots) * (WORK_NS_KNOT + WORK_NS_PAIR * self._pairs(obs))
        while evaluated < K:
            now = clock()
            size = min(int(c.chunk), K - evaluated)
            if work:  # the deterministic clock: the model's time of the samples so far
                over = (evaluated + size) * per_sample + WORK_NS_TAIL > budget
            else:
                over = now - start + self._chunk_time + self._tail_time > budget
            if budgeted and over:
                early = True
                break
            block = eps[evaluated : evaluated + size]
            block[:, 1:] = rng.standard_normal((size, m - 1, n)) * c.noise
            if evaluated == 0:
                block[0] = 0.0  # sample 0: the warm start itself
            terms = self.rollouts.costs(
                obs.q, obs.qd, self.controls, block, c.knot_dt, goal_pos, goal_axis,
                obs.obstacles, obs.obstacle_radii,
            )  # fmt: skip
            costs[evaluated : evaluated + size] = terms.sum(axis=1)
            evaluated += size
            chunk_times.append(clock() - now)
        tail = clock()
        status = MPPIStatus(evaluated, early, math.nan, math.nan, 0.0, 0.0)
        if evaluated:
            weights = softmax_weights(costs[:evaluated], float(c.temperature))
            self.controls = self.controls + np.tensordot(weights, eps[:evaluated], axes=1)
            status = status._replace(
                warm_cost=float(costs[0]),
                best_cost=float(costs[:evaluated].min()),
                effective_samples=float(1.0 / (weights @ weights)),
            )
        self.steps_done += 1
        self.early_stops += int(early)
        end = clock()
        # the estimates: medians, so that one slow chunk or tail (a page fault, an interrupt)
        # does not make the next step stop early
        if chunk_times:
            self._chunk_time = int(np.median(chunk_times))
        else:  # no chunk fitted: trust the estimate less, or one slow chunk would stop all
            self._chunk_time //= 2
        self._tails.append(end - tail)
        self._tail_time = int(np.median(self._tails))
        self._status = status._replace(elapsed=(end - start) * 1e-9)
        return self._status

    def _pairs(self, obs: Observation) -> int:
        """Arm capsule-obstacle pairs of the rollouts' collision cost (the work model's)."""
        return len(self.robot.capsules) * len(obs.obstacle_radii)

    def target(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint target ``(q*, q_dot*)`` of the nominal from ``(q, qd)``, shapes (n,).

        ``midpoint``: CR's, ``q* = q(t + dt/2)``, ``q_dot* = (q(t + dt) - q(t)) / dt``.
        ``matched``: ``q_dot* = v(t + dt)`` and the ``q*`` with which the inner joint PD
        ``q_ddot = kp (q* - q) + kd (q_dot* - q_dot)``, Euler-stepped at ``inner_hz`` over the
        period, ends it at the nominal's velocity (:func:`pd_period`).
        """
        u0 = self.controls[0]
        slope = (self.controls[1] - u0) / self.control_dt
        dt = self.dt

        def at(tau: float) -> np.ndarray:
            return q + tau * qd + tau**2 / 2.0 * u0 + tau**3 / 6.0 * slope

        if self.config.command == "midpoint":
            return at(dt / 2.0), (at(dt) - q) / dt
        v_end = qd + dt * u0 + dt**2 / 2.0 * slope
        (a_q, a_v), gain = self.pd_map
        drive = (v_end - a_q * q - a_v * qd) / gain  # kp q* + kd q_dot*
        kp, kd = float(self.config.tracking_kp), float(self.config.tracking_kd)
        if kp == 0.0:
            return q.copy(), drive / kd
        return (drive - kd * v_end) / kp, v_end

    def nominal_path(self) -> np.ndarray:
        """The nominal's knots from the last step's start, shape (H + 1, n) [rad]."""
        from amex.plan.rollouts import integrate

        q0, v0 = self._start
        if not len(q0):
            return np.zeros((0, self.robot.nv))
        q, _ = integrate(q0, v0, self.B @ self.controls, float(self.config.knot_dt))
        return np.vstack([q0, q])

    # ----------------------------------------------------------------------------- Method
    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: :meth:`restart`."""
        self.restart()
        self.t_controls = float(obs.t)

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: :meth:`sample`, then the joint target :meth:`target`."""
        self.sample(obs)
        q, qd = self.target(obs.q, obs.qd)
        return Command.joint(q, qd)

    def internals(self) -> dict[str, Any]:
        """The last step's :class:`MPPIStatus`, the early-stop count and the nominal TCP path.

        ``plan`` is the TCP position at the nominal's knots, shape (H + 1, 3) [m], computed when
        it is read (a :class:`~amex.core.lazy.LazyRows` of this step's knots, as CR's: the log's
        scene reads it every 5th step, and only the knots it draws).
        """
        s, path = self._status, self.nominal_path()
        positions, tcp = self.kinematics.frame_positions, self.robot.tcp_frame_id
        plan: Any = path
        if len(path):
            plan = LazyRows.rowwise(lambda q: positions(q, tcp), path, (positions, tcp))
        return LazyDict(**s._asdict(), early_stops=self.early_stops, plan=plan)
