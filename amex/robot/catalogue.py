"""The robots amex knows by name: where each description lives and the few facts not in it.

Everything else (kinematics, inertias, limits, collision capsules) is derived from the URDF by
:func:`amex.robot.model.build_robot`. The scene that suits each arm (scale, goal axis, reference
goal) is configuration: ``conf/robot/<name>.yaml``. DESIGN.md ("Other robots") records how the
start poses were chosen: every Task-1 and Task-3 goal of the robot's scene is reachable from them.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from amex.robot import chain7


class CatalogueEntry(NamedTuple):
    """A known robot: its description, arm joints (base to tip), TCP frame and start pose."""

    urdf: str
    joints: tuple[str, ...]
    tcp_frame: str
    q0: tuple[float, ...]


#: The Panda's neutral pose [rad]; its TCP is at (0.307, 0, 0.487), z-axis down.
PANDA_Q0 = (0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4)
_UR_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
#: A UR start pose with the tool pointing down, TCP at (0.40, 0.11, 0.30) for the UR5 [rad].
UR_Q0 = (0.0, -1.73, 2.06, -1.9, -1.57, 0.0)

CATALOGUE: dict[str, CatalogueEntry] = {
    "panda": CatalogueEntry(
        "example-robot-data:panda_description/urdf/panda_collision.urdf",
        tuple(f"panda_joint{i}" for i in range(1, 8)),
        "panda_hand_tcp",
        PANDA_Q0,
    ),
    "chain7": CatalogueEntry("amex:chain7", chain7.JOINTS, chain7.TCP_FRAME, chain7.Q0),
    "ur5": CatalogueEntry(
        "example-robot-data:ur_description/urdf/ur5_robot.urdf", _UR_JOINTS, "tool0", UR_Q0
    ),
    "ur10": CatalogueEntry(
        "example-robot-data:ur_description/urdf/ur10_robot.urdf", _UR_JOINTS, "tool0", UR_Q0
    ),
}
