"""The benchmark's scenes: Task 0-4 of the paper's Section IV-A, scaled to the robot.

Every scene is a pure function of ``(config, task, seed, env)``: environment ``env`` of a task is
the same for every method (a paired comparison). Goal and obstacle motions are closed-form
functions of time, so the simulation, the methods and the logs all see the same world.

Tasks:

* 0: the reference scene itself: goal = reference goal, no motion, no obstacle.
* 1: static goal on a ``3 x 5 x 10`` grid in a box around the reference goal.
* 2: goal starts at the reference goal and moves with a per-axis Gaussian velocity while
  ``t < window * T_ref``.
* 3: goal on a ``15 x 10`` grid on a plane beyond the box centre, moving as in Task 2, plus a static
  sphere obstacle at the midpoint between the start TCP position and the goal's start.
* 4: as 3, and the obstacle moves with a per-axis Gaussian velocity for the whole run.

Lengths and speeds of the original scenes are stated in the configuration at their original
values and marked with the power of ``scale`` they carry; the experiment layer converts them once
(:meth:`amex.experiment.config.RunConfig.scene`), so every function here takes a
:class:`ScenarioConfig` in scene units [m, m/s]. The reference goal follows from the robot's
start: its TCP plus the start-to-goal offset (:func:`reference_goal`), unless the config states
it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from amex.core.errors import ConfigError
from amex.core.scaling import scaled
from amex.core.schema import SIGNED

TASKS = (0, 1, 2, 3, 4)
#: The original start-to-goal offset: reference goal (0.75, -1.4, 1.7) minus the chain's start
#: TCP (0.3648, -2.5475, 1.8312), rounded to the millimetre [m, original units].
ORIGINAL_REFERENCE_OFFSET = (0.385, 1.147, -0.131)


@dataclass
class ScenarioConfig:
    """Distributions of the scenes. Lengths/speeds are the original's, multiplied by ``scale``.

    Attributes:
        scale: factor from the original scenes to ours (lengths and speeds) [-].
        reference_goal: goal of the reference plan, Task 0's goal [m] (not scaled; default: the
            default robot's, the Panda); empty: the robot's start TCP plus ``reference_offset``
            (:func:`reference_goal`).
        reference_offset: start-to-goal offset of the reference plan (original units) [m].
        goal_axis: required TCP z-axis at the goal (unit) [-].
        box_size: Task 1 box around the reference goal (original 0.7 x 0.8 x 1.8 m) [m].
        box_grid: grid points along x, y, z in the box (original 3 x 5 x 10).
        goal_speed_std: std of each goal velocity component (original 0.1 m/s) [m/s].
        goal_motion_window: the goal moves while ``t < window * T_ref`` (original 0.7) [-].
        plane_offset: Task 3 plane distance beyond the box centre along x (original 0.35 m) [m].
        plane_grid: grid points along y, z on the plane (original 10 x 15 = 150).
        obstacle_radius: sphere radius (original 0.1 m) [m].
        obstacle_speed_std: std of each obstacle velocity component, Task 4 (original 0.1) [m/s].
        plane_reference: Tasks 3-4 plan their reference to the plane's centre, as the original
            (default: every task plans to ``reference_goal``, the box centre).
    """

    scale: float = 0.2
    reference_goal: list[float] = field(default_factory=lambda: [0.384, 0.229, 0.461])
    reference_offset: list[float] = field(
        default_factory=lambda: list(ORIGINAL_REFERENCE_OFFSET), metadata=scaled(1)
    )
    goal_axis: list[float] = field(default_factory=lambda: [0.0, 0.0, -1.0])
    box_size: list[float] = field(default_factory=lambda: [0.7, 0.8, 1.8], metadata=scaled(1))
    box_grid: list[int] = field(default_factory=lambda: [3, 5, 10])
    goal_speed_std: float = field(default=0.1, metadata=scaled(1))
    goal_motion_window: float = 0.7
    # either side of the box centre
    plane_offset: float = field(default=0.35, metadata={**scaled(1), **SIGNED})
    plane_grid: list[int] = field(default_factory=lambda: [15, 10])
    obstacle_radius: float = field(default=0.1, metadata=scaled(1))
    obstacle_speed_std: float = field(default=0.1, metadata=scaled(1))
    plane_reference: bool = False

    def validate(self) -> None:
        """Raise :class:`ConfigError` for values no scene can be built from."""
        if not self.scale > 0:
            raise ConfigError.invalid("scenario.scale", self.scale, "a number > 0")
        if len(self.reference_goal) not in (0, 3):
            raise ConfigError.invalid(
                "scenario.reference_goal", self.reference_goal, "[x, y, z] [m], or [] (derived)"
            )
        if len(self.reference_offset) != 3:
            raise ConfigError.invalid(
                "scenario.reference_offset", self.reference_offset, "[x, y, z] [m]"
            )
        axis = np.asarray(self.goal_axis, dtype=float)
        if axis.shape != (3,) or not np.isclose(np.linalg.norm(axis), 1.0):
            raise ConfigError.invalid("scenario.goal_axis", self.goal_axis, "a unit 3-vector")
        if len(self.box_size) != 3 or min(self.box_size) < 0:
            raise ConfigError.invalid("scenario.box_size", self.box_size, "3 lengths >= 0 [m]")
        if len(self.box_grid) != 3 or min(self.box_grid) < 1:
            raise ConfigError.invalid("scenario.box_grid", self.box_grid, "3 counts >= 1")
        if len(self.plane_grid) != 2 or min(self.plane_grid) < 1:
            raise ConfigError.invalid("scenario.plane_grid", self.plane_grid, "2 counts >= 1")
        for key in ("goal_speed_std", "obstacle_speed_std", "obstacle_radius"):
            if getattr(self, key) < 0:
                raise ConfigError.invalid(f"scenario.{key}", getattr(self, key), "a number >= 0")
        if not 0 <= self.goal_motion_window <= 1:
            raise ConfigError.invalid(
                "scenario.goal_motion_window", self.goal_motion_window, "a fraction in [0, 1]"
            )


@dataclass(frozen=True)
class Scenario:
    """One environment: where the goal and the obstacles are at every instant.

    Attributes:
        task: task number, 0-4.
        env: environment index within the task.
        seed: the run's seed.
        goal_start: goal position at t = 0, shape (3,) [m].
        goal_velocity: constant goal velocity while it moves, shape (3,) [m/s].
        goal_stop_time: the goal stops moving at this time [s].
        goal_axis: required TCP z-axis at the goal, shape (3,).
        obstacle_start: obstacle centres at t = 0, shape (k, 3) [m].
        obstacle_velocity: obstacle velocities, shape (k, 3) [m/s].
        obstacle_radii: shape (k,) [m].
    """

    task: int
    env: int
    seed: int
    goal_start: np.ndarray
    goal_velocity: np.ndarray
    goal_stop_time: float
    goal_axis: np.ndarray
    obstacle_start: np.ndarray
    obstacle_velocity: np.ndarray
    obstacle_radii: np.ndarray

    @property
    def n_obstacles(self) -> int:
        """Number of obstacle spheres."""
        return len(self.obstacle_radii)

    def goal_at(self, t: float) -> np.ndarray:
        """Goal position at time ``t`` [s], shape (3,) [m]."""
        return self.goal_start + self.goal_velocity * min(t, self.goal_stop_time)

    def obstacles_at(self, t: float) -> np.ndarray:
        """Obstacle centres at time ``t`` [s], shape (k, 3) [m]."""
        return self.obstacle_start + self.obstacle_velocity * t


def box_grid(center: np.ndarray, size: np.ndarray, counts: list[int]) -> np.ndarray:
    """Points of a regular grid filling a box, shape (prod(counts), 3) [m], x slowest."""
    axes = [
        np.linspace(c - s / 2, c + s / 2, n) if n > 1 else np.array([c])
        for c, s, n in zip(center, size, counts, strict=True)
    ]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def reference_goal(config: ScenarioConfig, start_tcp: np.ndarray) -> np.ndarray:
    """The reference plan's goal, shape (3,) [m].

    ``config.reference_goal`` if stated, else the robot's start TCP ``start_tcp`` plus the
    original start-to-goal offset times the scale.
    """
    if len(config.reference_goal):
        return np.asarray(config.reference_goal, dtype=float)
    return np.asarray(start_tcp, dtype=float) + np.asarray(config.reference_offset, dtype=float)


def with_reference_goal(config: ScenarioConfig, start_tcp: np.ndarray) -> ScenarioConfig:
    """A copy of ``config`` whose ``reference_goal`` is stated (:func:`reference_goal`)."""
    goal = reference_goal(config, start_tcp)
    return dataclasses.replace(config, reference_goal=[float(x) for x in goal])


def plan_goal(config: ScenarioConfig, task: int, start_tcp: np.ndarray) -> np.ndarray:
    """The goal of the reference plan of ``task``, shape (3,) [m].

    :func:`reference_goal`, or with ``plane_reference`` the Task-3/4 plane's centre for those.
    """
    goal = reference_goal(config, start_tcp)
    if config.plane_reference and task in (3, 4):
        goal = goal + np.array([config.plane_offset, 0.0, 0.0])
    return goal


def goal_grid(config: ScenarioConfig, task: int) -> np.ndarray:
    """Candidate goal start positions of Task 1 (box) or Task 3/4 (plane), shape (n, 3) [m].

    ``config.reference_goal`` must be stated (:func:`with_reference_goal`).
    """
    center = np.asarray(config.reference_goal, dtype=float)
    if center.shape != (3,):
        raise ConfigError("goal_grid needs a stated scenario.reference_goal (with_reference_goal)")
    size = np.asarray(config.box_size, dtype=float)
    if task == 1:
        return box_grid(center, size, list(config.box_grid))
    plane_center = center + np.array([config.plane_offset, 0.0, 0.0])
    ny, nz = config.plane_grid
    return box_grid(plane_center, np.array([0.0, size[1], size[2]]), [1, ny, nz])


def make_scenario(
    config: ScenarioConfig,
    task: int,
    seed: int,
    env: int,
    start_tcp: np.ndarray,
    reference_duration: float,
) -> Scenario:
    """Build environment ``env`` of ``task`` for ``seed``.

    Grid goals are visited in a seeded random order (so a run with few episodes still spreads over
    the grid); ``env`` beyond the grid size wraps around. Velocities are drawn from a generator
    seeded by ``SeedSequence([seed, task, env])`` (never global state), independent of the method.

    Args:
        config: scene distributions.
        task: 0-4.
        seed: run seed (>= 0).
        env: environment index (>= 0).
        start_tcp: TCP position at the start configuration, shape (3,) [m].
        reference_duration: T_ref [s] (the goal moves during ``window * T_ref``).
    """
    if task not in TASKS:
        raise ConfigError.invalid("task", task, TASKS)
    config = with_reference_goal(config, start_tcp)
    rng = np.random.default_rng(np.random.SeedSequence([seed, task, env]))
    reference = np.asarray(config.reference_goal, dtype=float)
    goal_velocity = np.zeros(3)
    obstacle_start = np.zeros((0, 3))
    obstacle_velocity = np.zeros((0, 3))
    radii = np.zeros(0)
    if task in (1, 3, 4):
        grid = goal_grid(config, task)
        order = np.random.default_rng(np.random.SeedSequence([seed, task])).permutation(len(grid))
        goal_start = grid[order[env % len(grid)]]
    else:
        goal_start = reference.copy()
    if task >= 2:
        goal_velocity = rng.normal(0.0, config.goal_speed_std, size=3)
    if task >= 3:
        obstacle_start = ((np.asarray(start_tcp, dtype=float) + goal_start) / 2)[None, :]
        radii = np.array([config.obstacle_radius])
        obstacle_velocity = np.zeros((1, 3))
    if task == 4:
        obstacle_velocity = rng.normal(0.0, config.obstacle_speed_std, size=(1, 3))
    return Scenario(
        task=task,
        env=env,
        seed=seed,
        goal_start=goal_start,
        goal_velocity=goal_velocity,
        goal_stop_time=config.goal_motion_window * reference_duration,
        goal_axis=np.asarray(config.goal_axis, dtype=float),
        obstacle_start=obstacle_start,
        obstacle_velocity=obstacle_velocity,
        obstacle_radii=radii,
    )
