"""Random trajectory problems the planner's tests share."""

from __future__ import annotations

import numpy as np

from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.plan.weights import CollisionWeights


def problem_near_obstacles(robot, rng, T: int, k: int, metric: bool) -> TrajectoryProblem:
    """A random problem with ``k`` spheres about the TCP's start (so pairs come near)."""
    tcp = robot.tcp_pose(robot.q0).translation
    weights = CollisionWeights(collision=10.0, collision_margin=0.05)
    costs = TrajectoryCosts(weights, tuple(rng.uniform(0.5, 2.0, robot.nv)) if metric else ())
    return TrajectoryProblem(
        q_start=robot.q0 + rng.normal(scale=0.1, size=robot.nv),
        v_start=rng.normal(scale=0.1, size=robot.nv),
        steps=T,
        dt=0.01,
        goal_pos=tcp + rng.normal(scale=0.2, size=3),
        goal_axis=np.array([0.0, 0.0, -1.0]),
        obstacles=tcp + rng.normal(scale=0.15, size=(k, 3)),
        obstacle_radii=rng.uniform(0.03, 0.1, k),
        costs=costs,
    )
