"""The paper's own robot, generated as a URDF from the facts of the authors' model file.

``robot.ors`` of the authors' harness (DESIGN.md, "The original experiment"): a fixed stem, a
capsule 2 m long standing on the origin; joint 1 on its top at (0, 0, 2), turned by roll pi/2;
joints 2-7 each 0.4 m further along the previous link's z-axis and turned pi/4 about it; every
hinge turns about its frame's local x-axis; links 1-6 are capsules of length 0.4 (joint to
joint) and radius 0.1; the tool centre point is 0.2 m beyond joint 7 and carries a tiny sphere
(the original's end-effector capsule of radius 2e-4). The stem is never collision-checked, so it
is a visual only. Reach: 2.6 m from the shoulder.

The original simulation was kinematic and had no masses. For ``sim=dynamic`` the links get
masses of 4, 3.5, 3, 2.5, 2 and 1.5 kg (solid cylinders) and the tip 0.5 kg, and torque limits
about six times the largest gravity torque each joint can see (the shoulder needs 170 N m at the
start pose; free reaching motions peak at 180-270 N m there, DMP's collision-avoidance transients
on Tasks 3-4 at up to 2000 N m, which saturate: with limits of twice the gravity torque such
saturations made a few of those episodes diverge). The original had no joint limits; the URDF
states +-2 pi.
"""

from __future__ import annotations

import math

#: Link masses of links 1-6 and the tip (link 7) [kg] (not in the original: it was kinematic).
MASSES = (4.0, 3.5, 3.0, 2.5, 2.0, 1.5, 0.5)
#: Symmetric torque limits of joints 1-7 [N m].
TORQUE_LIMITS = (1000.0, 600.0, 400.0, 250.0, 120.0, 40.0, 8.0)
#: Joint speed limit [rad/s] (the original had none; used for the divergence check).
VELOCITY_LIMIT = 3.0
LINK_LENGTH = 0.4  # [m]
LINK_RADIUS = 0.1  # [m]
TCP_DISTANCE = 0.2  # [m] joint 7 to the tool centre point
TIP_RADIUS = 2e-4  # [m] the original's end-effector capsule
STEM_LENGTH = 2.0  # [m]
JOINTS = tuple(f"joint{i}" for i in range(1, 8))
TCP_FRAME = "tcp"
Q0 = (0.1,) * 7  # [rad] the original's start


def _inertial(mass: float, com_z: float, radius: float, length: float) -> str:
    """A solid cylinder along z (a sphere of ``radius`` when ``length`` is 0)."""
    if length > 0.0:
        ixx = mass * (3.0 * radius**2 + length**2) / 12.0
        izz = mass * radius**2 / 2.0
    else:
        ixx = izz = 0.4 * mass * radius**2
    return (
        f'<inertial><origin xyz="0 0 {com_z!r}"/><mass value="{mass!r}"/>'
        f'<inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{ixx!r}" iyz="0" izz="{izz!r}"/></inertial>'
    )


def _capsule(tag: str, radius: float, length: float, z0: float) -> str:
    """A capsule along z from z0 to z0 + length as a cylinder plus two end spheres."""
    parts = [
        f'<{tag}><origin xyz="0 0 {z0 + length / 2.0!r}"/><geometry>'
        f'<cylinder radius="{radius!r}" length="{length!r}"/></geometry></{tag}>'
    ]
    for z in (z0, z0 + length):
        parts.append(
            f'<{tag}><origin xyz="0 0 {z!r}"/><geometry><sphere radius="{radius!r}"/>'
            f"</geometry></{tag}>"
        )
    return "".join(parts)


def chain7_urdf() -> str:
    """The URDF text of the original 7-hinge chain (module notes)."""
    lines = ['<?xml version="1.0"?>', '<robot name="chain7">', '<link name="base">']
    lines.append(_capsule("visual", LINK_RADIUS, STEM_LENGTH, 0.0))  # the stem: visual only
    lines.append("</link>")
    parent = "base"
    limit_pi = f"{2.0 * math.pi!r}"
    for i, name in enumerate(JOINTS):
        child = f"link{i + 1}"
        if i == 0:
            origin = f'<origin xyz="0 0 {STEM_LENGTH!r}" rpy="{math.pi / 2.0!r} 0 0"/>'
        else:
            origin = f'<origin xyz="0 0 {LINK_LENGTH!r}" rpy="0 0 {math.pi / 4.0!r}"/>'
        lines.append(
            f'<joint name="{name}" type="revolute">{origin}<parent link="{parent}"/>'
            f'<child link="{child}"/><axis xyz="1 0 0"/>'
            f'<limit lower="-{limit_pi}" upper="{limit_pi}" effort="{TORQUE_LIMITS[i]!r}" '
            f'velocity="{VELOCITY_LIMIT!r}"/></joint>'
        )
        lines.append(f'<link name="{child}">')
        if i < 6:
            lines.append(_inertial(MASSES[i], LINK_LENGTH / 2.0, LINK_RADIUS, LINK_LENGTH))
            for tag in ("collision", "visual"):
                lines.append(_capsule(tag, LINK_RADIUS, LINK_LENGTH, 0.0))
        else:
            lines.append(_inertial(MASSES[i], TCP_DISTANCE, 0.05, 0.0))
            for tag in ("collision", "visual"):
                lines.append(
                    f'<{tag}><origin xyz="0 0 {TCP_DISTANCE!r}"/><geometry>'
                    f'<sphere radius="{TIP_RADIUS!r}"/></geometry></{tag}>'
                )
        lines.append("</link>")
        parent = child
    lines.append(
        f'<joint name="tcp_joint" type="fixed"><origin xyz="0 0 {TCP_DISTANCE!r}"/>'
        f'<parent link="link7"/><child link="{TCP_FRAME}"/></joint>'
    )
    lines.append(f'<link name="{TCP_FRAME}"/>')
    lines.append("</robot>")
    return "\n".join(lines) + "\n"
