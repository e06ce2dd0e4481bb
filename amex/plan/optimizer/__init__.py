"""Trajectory optimization in joint space: ours (Levenberg-Gauss-Newton) and the authors' Newton.

The public names of the planner's optimizer, from the modules that define them; the cost f(x)
and the solvers' derivations are in docs/planner.md.
"""

from amex.plan.batch_kinematics import (
    BatchKinematics,
    BatchPoses,
    CapsuleDistances,
    batch_kinematics,
)
from amex.plan.optimizer.assembly import CompiledAssembly
from amex.plan.optimizer.levenberg import solve_trajectory
from amex.plan.optimizer.linearize import NormalEquations, build_normal_equations
from amex.plan.optimizer.loop_calls import ReplanLoop
from amex.plan.optimizer.newton import solve_trajectory_newton
from amex.plan.optimizer.residuals import KnotFrames, trajectory_residuals
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem, TrajectorySolution

__all__ = [
    "BatchKinematics",
    "BatchPoses",
    "CapsuleDistances",
    "CompiledAssembly",
    "KnotFrames",
    "NormalEquations",
    "ReplanLoop",
    "TrajectoryCosts",
    "TrajectoryProblem",
    "TrajectorySolution",
    "batch_kinematics",
    "build_normal_equations",
    "solve_trajectory",
    "solve_trajectory_newton",
    "trajectory_residuals",
]
