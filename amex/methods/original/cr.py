"""Continuous replanning as the authors' harness ran it (``mpc.cpp`` at commit b475fa1fe).

``implementation=original method=cr`` selects it (``experiment=original`` sets it). The
original's costs (final TCP velocity; their collision proxy cost ``(sum_p d1_p d2_p)^2`` per knot
at weight 1, :mod:`amex.plan.optimizer.proxy`, unless ``method.collision_cost=hinge``) solved by
their Newton method
(:func:`~amex.plan.optimizer.solve_trajectory_newton`); a horizon shrinking by one knot per
outer step with the measured configurations of the two previous steps as its fixed prefix; the
command ``q* = x_1``, ``q_dot* = (x_1 - x_0) / dt``; the episode ends once fewer than 2 knots
remain. Against ours: docs/planner.md, "The authors' CR".
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from amex.core.errors import ConfigError
from amex.core.types import Command
from amex.methods.base import Method, Observation
from amex.methods.cr import CRConfig, CRStatus
from amex.plan.knots import resample_knots
from amex.plan.weights import CollisionWeights

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel


class CROriginal(Method):
    """The authors' continuous replanning (module notes).

    Args:
        plan: the reference plan; its joint trajectory resampled at ``dt`` is the first warm
            start, its metric that of the acceleration term.
        config: :class:`~amex.methods.cr.CRConfig`; collision_margin (the proxy's margin [m]),
            collision_cost (``auto``: their proxy), max_iterations (Newton steps per replan,
            original 20) and min_steps (the episode ends below this many knots, original 2)
            apply.
        dt: the knot spacing and outer period [s] (the original's 0.01 s for both).
        robot: the arm; required.
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
        from amex.plan.optimizer import CompiledAssembly, TrajectoryCosts

        super().__init__(plan, config, dt, robot)  # checks robot and plan.q too (needs_robot)
        c, robot, metric = self.config, self.robot, plan.metric
        steps = int(round(plan.duration / self.dt))
        if steps < 2:
            raise ConfigError.invalid("dt", dt, f"<= T_ref / 2 = {plan.duration / 2:g} [s]")
        Q = np.array(resample_knots(plan.q, 0.0, self.dt / plan.dt, steps + 1), dtype=float)
        weights = CollisionWeights(collision_margin=c.collision_margin)  # the original's weights
        self.costs = TrajectoryCosts.from_weights(
            weights, metric, final_velocity_space="tcp", collision_cost=c.collision_form("proxy")
        )
        self.robot = robot
        self.assembly = CompiledAssembly(robot)  # the solver's buffers, kept between steps
        self.reference_q = Q
        self.max_iterations = int(c.max_iterations)
        self.min_steps = int(c.min_steps)
        self.restart()

    def restart(self) -> None:
        """A new execution: the reference's knots, the start at rest as the prefix."""
        self._x = self.reference_q.copy()
        self._steps = len(self._x) - 1
        start = self.reference_q[0]
        self._prefix = (start, start)
        self._measured: list[np.ndarray] = []
        self._finished = False
        self._status = CRStatus("shrink", self._steps, 0, math.nan, False, 0.0)

    @property
    def finished(self) -> bool:
        """Whether fewer than ``min_steps`` knots remained at the last step: the episode ends."""
        return self._finished

    @property
    def knots(self) -> np.ndarray:
        """The current plan's knots, shape (T + 1, n) [rad]."""
        return self._x

    @property
    def status(self) -> CRStatus:
        """What the last step did (as :attr:`amex.methods.cr.CR.status`)."""
        return self._status

    def replan(self, obs: Observation) -> CRStatus:
        """One ``MPC::replan``: shrink, shift, re-optimize from the measured prefix."""
        from amex.plan.optimizer import TrajectoryProblem, solve_trajectory_newton

        tic = time.perf_counter()
        self._steps -= 1
        self._measured.append(np.array(obs.q, dtype=float))
        if self._steps < 3:
            self._x = self._x[-3:]
            self._status = CRStatus("hold", self._steps, 0, math.nan, False, 0.0)
            return self._status
        if len(self._measured) > 2:
            self._prefix = (self._measured[-3], self._measured[-2])
        self._x = self._x[1:]
        before, last = self._prefix
        problem = TrajectoryProblem(
            q_start=last,
            v_start=(last - before) / self.dt,
            steps=len(self._x),
            dt=self.dt,
            goal_pos=obs.goal[:3],
            goal_axis=obs.goal[3:6],
            obstacles=obs.obstacles,
            obstacle_radii=obs.obstacle_radii,
            costs=self.costs,
        )
        solution = solve_trajectory_newton(
            self.robot,
            problem,
            np.vstack([last, self._x]),
            max_iterations=self.max_iterations,
            assembly=self.assembly,
        )
        self._x = solution.q[1:]
        self._status = CRStatus(
            "shrink",
            self._steps,
            solution.iterations,
            solution.cost,
            solution.converged,
            time.perf_counter() - tic,
        )
        return self._status

    def reset(self, obs: Observation) -> None:
        """See :meth:`Method.reset`."""
        self.restart()

    def step(self, obs: Observation) -> Command:
        """See :meth:`Method.step`: replan, then the next knot (module notes)."""
        if self._steps < self.min_steps:
            self._finished = True
        else:
            self.replan(obs)
        x = self._x
        return Command.joint(x[1].copy(), (x[1] - x[0]) / self.dt)

    def internals(self) -> dict[str, Any]:
        """Mode, horizon, iterations, cost, converged and solve time of the last step."""
        s = self._status
        return {
            "mode": s.mode,
            "steps": s.steps,
            "iterations": s.iterations,
            "cost": s.cost,
            "converged": s.converged,
            "solve_time": s.solve_time,
        }
