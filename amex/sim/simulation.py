"""The MuJoCo world of one episode: the arm and its obstacle spheres, and how it may differ.

:class:`Simulation` builds the arm's compiled MuJoCo model (shared, copied per episode) with the
scenario's obstacle spheres as mocap bodies; :class:`MismatchConfig` makes the simulated arm
differ from the controller's model (masses, friction, damping), as the paper's PR2 "does not
accelerate as desired".
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

from amex.core.errors import ConfigError
from amex.robot import RobotModel
from amex.sim.scenario import Scenario


@dataclass
class MismatchConfig:
    """How the simulated arm differs from the controller's model; defaults: not at all.

    The paper's PR2 "does not accelerate as desired"; this reproduces that in simulation.

    Attributes:
        mass_scale: factor on every link's mass and inertia in the simulation [-].
        friction: Coulomb friction (MuJoCo ``frictionloss``) at every joint [N m].
        damping: viscous damping at every joint [N m s/rad].
    """

    mass_scale: float = 1.0
    friction: float = 0.0
    damping: float = 0.0

    def validate(self) -> None:
        """Raise :class:`ConfigError` for non-physical values."""
        if not self.mass_scale > 0:
            raise ConfigError.invalid("mismatch.mass_scale", self.mass_scale, "a factor > 0")
        for key in ("friction", "damping"):
            if not getattr(self, key) >= 0:
                raise ConfigError.invalid(f"mismatch.{key}", getattr(self, key), "a value >= 0")


class Simulation:
    """MuJoCo world for one scenario: the arm plus its obstacle spheres (mocap bodies)."""

    def __init__(
        self,
        robot: RobotModel,
        scenario: Scenario,
        inner_hz: float,
        mismatch: MismatchConfig | None = None,
    ) -> None:
        # a private copy: obstacle sizes and mismatch are per episode, the compiled model is shared
        self.model = copy.copy(robot.build_mujoco(scenario.n_obstacles, timestep=1.0 / inner_hz))
        if mismatch is not None:
            self.model.body_mass[:] *= mismatch.mass_scale
            self.model.body_inertia[:] *= mismatch.mass_scale
            self.model.dof_frictionloss[:] = mismatch.friction
            self.model.dof_damping[:] = mismatch.damping
        for k, r in enumerate(scenario.obstacle_radii):
            gid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, f"obstacle_{k}")
            self.model.geom_size[gid, 0] = r
            self.model.geom_rbound[gid] = r
        self.data = mujoco.MjData(self.model)
        self.data.qpos[:] = robot.q0
        self.data.qvel[:] = 0.0
        self.set_obstacles(scenario.obstacles_at(0.0))
        mujoco.mj_forward(self.model, self.data)

    def set_obstacles(self, centers: np.ndarray) -> None:
        """Move the obstacle spheres, shape (k, 3) [m]."""
        if len(centers):
            self.data.mocap_pos[:] = centers
