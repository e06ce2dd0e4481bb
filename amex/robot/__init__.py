"""The robot layer: a description (URDF + a few facts) becomes Pinocchio, coal and MuJoCo views.

* :mod:`amex.robot.description`: :class:`RobotConfig` (what a user writes) and its resolution
  into a cleaned :class:`RobotDescription`.
* :mod:`amex.robot.catalogue`: the robots known by name (``panda``, ``chain7``, ``ur5``, ``ur10``).
* :mod:`amex.robot.chain7`: the paper's own 7-hinge chain, generated as a URDF.
* :mod:`amex.robot.capsules`: collision capsules merged from primitives or fitted to meshes.
* :mod:`amex.robot.model`: :class:`RobotModel`, built by :func:`build_robot`.

The rest of amex speaks only of "the robot": ``load_robot(config)``.
"""

from __future__ import annotations

from amex.robot.capsules import Capsule
from amex.robot.catalogue import CATALOGUE, PANDA_Q0
from amex.robot.description import RobotConfig, RobotDescription, resolve
from amex.robot.model import OBSTACLE_PARK, RobotModel, build_robot

_LOADED: dict[str, RobotModel] = {}


def load_robot(config: RobotConfig | str = "panda") -> RobotModel:
    """The robot of ``config`` (a :class:`RobotConfig`, or a catalogue name).

    Built once per configuration and process (validation and the run share it); treat the
    result as read-only.

    Raises:
        ConfigError: one line naming the bad value (see :func:`build_robot`).
    """
    if isinstance(config, str):
        config = RobotConfig(name=config)
    key = repr(config)
    robot = _LOADED.get(key)
    if robot is None:
        if len(_LOADED) >= 8:
            _LOADED.clear()
        robot = _LOADED[key] = build_robot(resolve(config))
    return robot


__all__ = [
    "CATALOGUE",
    "OBSTACLE_PARK",
    "PANDA_Q0",
    "Capsule",
    "RobotConfig",
    "RobotDescription",
    "RobotModel",
    "build_robot",
    "load_robot",
    "resolve",
]
