"""Generate my_arm.urdf: a small 6-joint arm of capsule links (run it to change the arm).

Each link is a capsule (a cylinder and two end spheres, which amex merges into one capsule) with
the inertia of a solid cylinder; the tool frame sits at the end of the last link.
"""

from pathlib import Path

#: (joint name, axis, link length [m], mass [kg], radius [m], torque limit [N m])
LINKS = (
    ("base_yaw", "0 0 1", 0.16, 3.0, 0.06, 150.0),
    ("shoulder", "0 1 0", 0.42, 2.5, 0.05, 150.0),
    ("elbow", "0 1 0", 0.38, 2.0, 0.045, 80.0),
    ("wrist_pitch", "0 1 0", 0.10, 0.8, 0.04, 30.0),
    ("wrist_yaw", "0 0 1", 0.10, 0.6, 0.035, 30.0),
    ("wrist_roll", "0 1 0", 0.08, 0.4, 0.03, 20.0),
)
BASE_HEIGHT = 0.05  # [m] of the first joint above the base


def _capsule(tag: str, radius: float, length: float) -> list[str]:
    mid = f'<origin xyz="0 0 {length / 2}"/>'
    parts = [f'<{tag}>{mid}<geometry><cylinder radius="{radius}" length="{length}"/>'
             f"</geometry></{tag}>"]  # fmt: skip
    for z in (0.0, length):
        parts.append(
            f'<{tag}><origin xyz="0 0 {z}"/><geometry><sphere radius="{radius}"/></geometry>'
            f"</{tag}>"
        )
    return parts


def my_arm_urdf() -> str:
    """The URDF text of the arm."""
    out = ['<?xml version="1.0"?>', '<robot name="my_arm">', '<link name="base"/>']
    parent, offset = "base", BASE_HEIGHT
    for i, (joint, axis, length, mass, radius, effort) in enumerate(LINKS):
        child = f"link{i + 1}"
        out.append(
            f'<joint name="{joint}" type="revolute"><origin xyz="0 0 {offset}"/>'
            f'<parent link="{parent}"/><child link="{child}"/><axis xyz="{axis}"/>'
            f'<limit lower="-3.14" upper="3.14" effort="{effort}" velocity="3.0"/></joint>'
        )
        ixx = mass * (3 * radius**2 + length**2) / 12
        izz = mass * radius**2 / 2
        out.append(
            f'<link name="{child}"><inertial><origin xyz="0 0 {length / 2}"/>'
            f'<mass value="{mass}"/><inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{ixx:.6g}" '
            f'iyz="0" izz="{izz:.6g}"/></inertial>'
        )
        for tag in ("collision", "visual"):
            out += _capsule(tag, radius, length)
        out.append("</link>")
        parent, offset = child, length
    out.append(
        f'<joint name="tool_joint" type="fixed"><origin xyz="0 0 {offset}"/>'
        f'<parent link="{parent}"/><child link="tool"/></joint>'
    )
    out += ['<link name="tool"/>', "</robot>"]
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    Path(__file__).with_name("my_arm.urdf").write_text(my_arm_urdf())
