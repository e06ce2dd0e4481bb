"""Continuous replanning (CR, the paper's Section IV-A): trajectory optimization every outer step.

Every outer step re-solves the reference plan's problem (:mod:`amex.plan.optimizer`: squared
joint accelerations, final TCP position, axis and their velocities, plus a collision term) from
the measured state ``(q, q_dot)`` to the current goal ``(g, axis)`` among the current obstacles,
on the shrinking horizon of knots ``t + k dt_knot``, ``k = 0..T``, ``T = round((T_ref - t) /
dt_knot)``, warm-started from the previous solution resampled at the new knots. It sends the
plan's state at the middle of the held outer period as a joint target, ``q* = q(t + dt/2)``,
``q_dot* = (q(t + dt) - q(t)) / dt``, for a joint PD task of the inner controller (the shared
``controller.joint`` gains). Below ``min_steps`` knots it holds the final knot; after T_ref it
replans on a receding ``tail_horizon`` and sends that plan's final knot.

The choices (midpoint command, the tail after T_ref, the two cost deviations from the original,
the real-time mode) and their measurements are in ``docs/methods/cr.md``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from amex.core.compiled import kernel
from amex.core.errors import ConfigError
from amex.core.lazy import LazyDict, LazyRows
from amex.core.scaling import scaled
from amex.core.types import Command
from amex.methods.base import Method, MethodConfig, Observation
from amex.plan.knots import resample_knots, whole_knot_rows
from amex.plan.weights import CollisionWeights

_new = tuple.__new__  # a NamedTuple made without its Python-level __new__ (the same tuple)
_F64 = np.dtype(np.float64)
#: ``method.collision_cost``: the implementation's own, ours, the authors'.
CR_COLLISION_COSTS = ("auto", "hinge", "proxy")

if TYPE_CHECKING:  # the optimizer needs Pinocchio; imported when a CR is built
    from amex.plan.optimizer import KnotFrames, ReplanLoop, TrajectorySolution
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


@dataclass
class CRConfig(CollisionWeights, MethodConfig):
    """CR settings: the reference plan's cost weights plus collision, solver limits, horizon rules.

    The cost weights are :class:`~amex.plan.weights.CollisionWeights`' with three defaults of
    CR's own (below). ``pos`` and ``dir`` (inherited) are unused: CR sends joint targets, tracked
    with the shared ``controller.joint`` gains (original 100/100).

    Attributes:
        final_axis: weight of the final TCP z-axis error (original 1e4; carries scale^2).
        collision: weight of the collision proxy term (original 1; here 10).
        collision_margin: distance at which the collision term starts [m] (original 0.1 m; a
            length in original units, :mod:`amex.core.scaling`).
        knot_dt: knot spacing of the replanning horizon [s] (the reference's 0.01 s).
        max_iterations: Gauss-Newton iterations per step, "until converged, capped" (original
            20).
        tolerance: stopping threshold on the relative cost decrease and on the step [rad].
        damping: smallest Levenberg term (original 1e-3).
        realtime: cap each step at ``realtime_iterations`` instead of ``max_iterations``.
        realtime_iterations: the real-time cap (a fixed small number, e.g. 2).
        min_steps: below this many remaining knots CR stops replanning (original 2).
        tail_horizon: receding horizon after T_ref [s], whose final knot is the target; 0
            holds the last final knot for ever (original).
        collision_cost: the collision term's form: ``hinge``, ours, ``max(0, 1 - d / margin)^2``
            per knot and pair; ``proxy``, the authors' ``(sum_p d1_p d2_p)^2`` per knot
            (:mod:`amex.plan.optimizer.proxy`); ``auto``, the implementation's own (ours:
            hinge; the authors' CR: proxy).
    """

    name: str = "cr"
    # The axis error is dimensionless while position errors shrink with the scene, so CR's
    # balance between them (goals beside an obstacle, where the axis must give way) carries
    # scale^2. plan.final_axis carries none: the reference goal is reached with the axis held
    # and no obstacle in the way, no trade-off to balance (docs/planner.md, "CR's costs").
    final_axis: float = field(default=1e4, metadata=scaled(2))  # [-] original
    collision: float = 10.0  # [-] original 1 (docs/planner.md, "CR's costs")
    collision_margin: float = field(default=0.1, metadata=scaled(1))  # [m] original
    knot_dt: float = 0.01  # [s] the reference's (original)
    max_iterations: int = 20  # [-] original
    tolerance: float = 1e-3  # [-, rad]
    damping: float = 1e-3  # [-] original
    realtime: bool = False
    realtime_iterations: int = 2  # [-]
    min_steps: int = 2  # [knots] original
    tail_horizon: float = 0.5  # [s]; 0: hold the final knot (original)
    collision_cost: str = "auto"  # hinge (ours) or proxy (the original)

    def collision_form(self, own: str) -> str:
        """The collision term's form, ``own`` (the implementation's) for ``auto``."""
        return own if self.collision_cost == "auto" else self.collision_cost

    def validate(self) -> None:
        """Raise :class:`ConfigError` for solver and horizon settings CR cannot run with."""
        if not (math.isfinite(self.knot_dt) and self.knot_dt > 0.0):
            raise ConfigError.invalid("method.knot_dt", self.knot_dt, "> 0 [s]")
        for key in ("max_iterations", "realtime_iterations", "min_steps"):
            value = getattr(self, key)
            if int(value) != value or value < 1:
                raise ConfigError.invalid(f"method.{key}", value, "an integer >= 1")
        if not (self.tolerance >= 0.0 and self.damping > 0.0):
            values = (self.tolerance, self.damping)
            raise ConfigError.invalid(
                "method.tolerance, damping", values, "tolerance >= 0, damping > 0"
            )
        if not (math.isfinite(self.tail_horizon) and self.tail_horizon >= 0.0):
            raise ConfigError.invalid("method.tail_horizon", self.tail_horizon, ">= 0 [s]")
        if self.collision_cost not in CR_COLLISION_COSTS:
            raise ConfigError.invalid(
                "method.collision_cost", self.collision_cost, CR_COLLISION_COSTS
            )


class CRStatus(NamedTuple):
    """What one CR step did.

    Attributes:
        mode: ``"shrink"`` (horizon ending at T_ref), ``"tail"`` (receding, after T_ref; the
            target is the final knot) or ``"hold"`` (no replanning).
        steps: horizon length T [knots] (0 when holding).
        iterations: Gauss-Newton iterations used.
        cost: trajectory cost of the solution (nan when holding).
        converged: whether the solver met its tolerance (False when holding).
        solve_time: wall time of the optimization [s].
    """

    mode: str
    steps: int
    iterations: int
    cost: float
    converged: bool
    solve_time: float


class JointTarget(NamedTuple):
    """CR's joint-space target (named as AMEX's and the DMP's task-space targets).

    Attributes:
        q_star: joint position target q*, shape (n,) [rad].
        qd_star: joint velocity target q_dot*, shape (n,) [rad/s].
    """

    q_star: np.ndarray
    qd_star: np.ndarray


def _columns(index: np.ndarray) -> np.ndarray | slice:
    """``index`` as a slice where it is a run of consecutive integers (views, not copies).

    ``index`` comes from :func:`~amex.plan.knots.whole_knots`: evenly spaced, repeats only where
    clamped at either end, so a span of ``len - 1`` without repeats at the ends is such a run.
    """
    first, last, count = int(index[0]), int(index[-1]), len(index)
    ends = count < 3 or (int(index[1]) == first + 1 and int(index[-2]) == last - 1)
    return slice(first, last + 1) if last - first == count - 1 and ends else index


class CR(Method):
    """Continuous replanning (see the module notes).

    Args:
        plan: the reference plan; its joint trajectory ``plan.q`` (shape (N + 1, n) [rad],
            ``plan.dt`` apart) is the first step's warm start, its metric diag(H) that of the
            acceleration cost (empty: identity).
        config: CR settings (None: :class:`CRConfig`'s defaults).
        dt: outer (control) period [s]: the command is the plan at t + dt / 2 (module notes).
        robot: the arm (kinematics and collision capsules of the optimizer); required.

    Raises:
        ConfigError: for invalid settings, a missing robot or a plan without its joints.

    Attributes:
        replan_loop: the one compiled call of CR's usual step, a shift by whole knots
            (:class:`~amex.plan.optimizer.ReplanLoop`: the solve and its joint target); None
            where it cannot run (the authors' proxy term, a single joint) or when set so:
            every solve then goes through :func:`~amex.plan.optimizer.solve_trajectory`, with
            the same numbers.
    """

    name = "cr"
    fresh_steps = True  # (Method.fresh_steps; tests/methods/test_fresh_steps.py)
    config_class = CRConfig
    needs_robot = True
    config: CRConfig
    robot: RobotModel

    def __init__(
        self,
        plan: ReferencePlan,
        config: CRConfig | None = None,
        dt: float = 0.01,
        robot: RobotModel | None = None,
    ) -> None:
        import amex.plan.optimizer as optimizer
        from amex.plan.optimizer import CompiledAssembly, TrajectoryCosts, batch_kinematics

        super().__init__(plan, config, dt, robot)  # checks robot and plan.q too (needs_robot)
        c, robot, metric = self.config, self.robot, plan.metric
        Q = np.array(plan.q, dtype=float)
        form = c.collision_form("hinge")
        self.costs = TrajectoryCosts.from_weights(c, metric, collision_cost=form)
        self.robot = robot
        self.kinematics = batch_kinematics(robot)
        self.assembly = CompiledAssembly(robot)  # the solver's buffers, kept between steps
        self._optimizer = optimizer  # its solver looked up at each call (bench_cr wraps it)
        self.reference_q = Q
        self.reference_dt = float(plan.dt)
        self.duration = (len(Q) - 1) * self.reference_dt
        self.knot_dt = float(c.knot_dt)
        self.iterations = int(c.realtime_iterations if c.realtime else c.max_iterations)
        self.tolerance, self.damping = float(c.tolerance), float(c.damping)
        self.min_steps = int(c.min_steps)
        self.tail_steps = int(round(c.tail_horizon / self.knot_dt))
        # the command's stride on a replanned horizon: q(t), q(t + dt / 2), q(t + dt)
        self._stride = dt / self.knot_dt / 2.0
        self._whole = abs(self._stride - round(self._stride)) <= 1e-9  # whole knots (whole_knots)
        # A shift by whole knots solved as one compiled call with its target (ReplanLoop);
        # None (where it cannot run, or set so to compare): every solve through solve_trajectory.
        settings = (self.iterations, self.tolerance, self.damping)
        target = (0.0 if self._whole else self._stride, float(dt))
        loop = optimizer.ReplanLoop(self.assembly, self.costs, self.knot_dt, settings, target)
        self.replan_loop: ReplanLoop | None = loop if loop.usable else None
        self.restart()

    # ----------------------------------------------------------------------------- state
    def restart(self) -> None:
        """Forget the last solution: the next step warm-starts from the reference plan."""
        self._knots = self.reference_q  # last solution, shape (T + 1, 7) [rad]
        self._frames: KnotFrames | None = None  # its frames at knots 1..T (the solver's)
        self._knots_t0, self._knots_dt = 0.0, self.reference_dt  # its first knot's time, spacing
        self._status = CRStatus("hold", 0, 0, math.nan, False, 0.0)
        self._target: JointTarget | None = None  # the last solve's, if it computed it

    @property
    def knots(self) -> np.ndarray:
        """The current plan: the last solution's knots, shape (T + 1, 7) [rad] (read-only)."""
        view = self._knots.view()
        view.flags.writeable = False
        return view

    @property
    def status(self) -> CRStatus:
        """What the last step did."""
        return self._status

    def horizon(self, t: float) -> tuple[str, int]:
        """The mode and horizon length T [knots] of a step at time ``t`` [s]."""
        remaining = int(round((self.duration - t) / self.knot_dt))
        if remaining >= self.min_steps:
            return "shrink", remaining
        if remaining <= 0 and self.tail_steps >= 1:
            return "tail", self.tail_steps
        return "hold", 0

    def plan(self, obs: Observation) -> CRStatus:
        """Re-optimize the remaining trajectory from ``obs`` (or hold); update :attr:`knots`.

        Raises:
            SolverError: for a non-finite observation or a failed solve (carries the problem).
        """
        tic = time.perf_counter()
        mode, steps = self.horizon(obs.t)
        if mode == "hold":
            self._status = CRStatus(mode, 0, 0, math.nan, False, 0.0)
            return self._status
        offset = (obs.t - self._knots_t0) / self._knots_dt
        stride = self.knot_dt / self._knots_dt
        rows = whole_knot_rows(len(self._knots), offset, stride, steps + 1)
        # An Observation's arrays are finite and new at each step: kept, not copied and checked
        # again (the solve copies the obstacles its frames keep, to compare with the next
        # step's). Anything else goes through the checks.
        o, r, q, v, goal = obs.obstacles, obs.obstacle_radii, obs.q, obs.qd, obs.goal
        arrays = type(o) is type(r) is type(q) is type(v) is np.ndarray
        arrays = arrays and o.dtype is r.dtype is q.dtype is v.dtype is _F64 and o.shape[1:] == (3,)
        solved = None
        if type(rows) is slice and arrays and self.replan_loop is not None:  # CR's usual step
            x = self._knots[rows.start + 1 : rows.stop]  # the free knots (a view)
            solved = self.replan_loop.solve(
                x, self._frames, rows.start, q, v, goal[:3], goal[3:6], o, r
            )
        if solved is None:
            solution = self._solve(obs, steps, offset, stride, rows, arrays)
            self._target = None
        else:
            solution, q_mid, qd = solved
            self._target = _new(JointTarget, (q_mid, qd)) if len(q_mid) else None
        self._knots, self._knots_t0, self._knots_dt = solution.q, float(obs.t), self.knot_dt
        self._frames = solution.frames
        took = time.perf_counter() - tic
        fields = (mode, steps, solution.iterations, solution.cost, solution.converged, took)
        self._status = _new(CRStatus, fields)  # CRStatus(*fields)
        return self._status

    def _solve(
        self,
        obs: Observation,
        steps: int,
        offset: float,
        stride: float,
        rows: slice | np.ndarray | None,
        arrays: bool,
    ) -> TrajectorySolution:
        """:func:`~amex.plan.optimizer.solve_trajectory` on the step's problem (module notes)."""
        optimizer = self._optimizer
        o, r, q, v = obs.obstacles, obs.obstacle_radii, obs.q, obs.qd
        if arrays:
            args = (q, v, steps, self.knot_dt, obs.goal[:3], obs.goal[3:6], o.copy(), r.copy())
            problem = optimizer.TrajectoryProblem.prechecked(*args, self.costs)
        else:
            args = (q, v, steps, self.knot_dt, obs.goal[:3], obs.goal[3:6], o, r)
            problem = optimizer.TrajectoryProblem(*args, self.costs)
        frames = None
        if rows is None:
            q_init = resample_knots(self._knots, offset, stride, steps + 1)
        else:  # a shift by whole knots: the last solution's frames at them are still right
            q_init = self._knots[rows]  # a view for a slice: solutions are new arrays
            if self._frames is not None:  # they hold the free knots 1..T: row i is column i - 1
                if isinstance(rows, slice):
                    frames = self._frames.take(slice(rows.start, rows.stop - 1))
                elif rows[1] >= 1:
                    frames = self._frames.take(_columns(rows[1:] - 1))
        return optimizer.solve_trajectory(  # type: ignore[no-any-return]
            self.robot,
            problem,
            q_init=q_init,
            max_iterations=self.iterations,
            tolerance=self.tolerance,
            damping=self.damping,
            init_frames=frames,
            assembly=self.assembly,
            compiled=True,  # one compiled call (the reference plan keeps the Python loop)
        )

    def target(self) -> JointTarget:
        """Joint target ``(q*, q_dot*)`` of the current plan (module notes), shapes (n,)."""
        knots = self._knots
        if self._status.mode != "shrink":  # hold, or the tail's final approach
            return JointTarget(knots[-1].copy(), np.zeros(knots.shape[1]))
        if self._target is not None:  # computed with the solve (ReplanLoop), taken once
            target, self._target = self._target, None
            return target
        stride = self._stride  # a shrink step's knots are knot_dt apart
        if self._whole or len(knots) < 2:
            q = resample_knots(knots, 0.0, stride, 3)
            return JointTarget(q[1], (q[2] - q[0]) / self.dt)
        n = knots.shape[1]
        q_mid, qd = np.empty(n), np.empty(n)
        blend = kernel("amex.plan.knots_kernels", "midpoint_target")
        blend(knots, stride, self.dt, q_mid, qd)  # the two lines above, compiled
        return _new(JointTarget, (q_mid, qd))

    # ----------------------------------------------------------------------------- Method
    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`: :meth:`restart`."""
        self.restart()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: :meth:`plan`, then the joint target :meth:`target`."""
        self.plan(obs)
        return Command.joint(*self.target())

    def internals(self) -> dict[str, Any]:
        """Mode, horizon steps, iterations, cost, converged, solve time and the planned TCP path.

        ``plan`` is the TCP position at every knot of the current plan, shape (T + 1, 3) [m],
        computed by batched kinematics (~0.1 ms for 400 knots) only when it is read: the dict
        is a :class:`~amex.core.lazy.LazyDict` holding this step's knots (a new array at each
        solve, never written in place), so a reader may read it later and still get this step's;
        a :class:`~amex.core.lazy.LazyRows`, so the log's scene computes only the knots it draws.
        """
        s, knots, kinematics, tcp = (
            self._status,
            self._knots,
            self.kinematics,
            self.robot.tcp_frame_id,
        )
        positions = kinematics.frame_positions
        return LazyDict(
            mode=s.mode,
            steps=s.steps,
            iterations=s.iterations,
            cost=s.cost,
            converged=s.converged,
            solve_time=s.solve_time,
            plan=LazyRows.rowwise(lambda q: positions(q, tcp), knots, (positions, tcp)),
        )
