"""Generate my_arm.urdf: a small 6-joint arm of capsule links (run it to change the arm)."""
import math
L = [("base_yaw", "z", 0.0, 0.16), ("shoulder", "y", 0.0, 0.42), ("elbow", "y", 0.0, 0.38),
     ("wrist_pitch", "y", 0.0, 0.10), ("wrist_yaw", "z", 0.0, 0.10), ("wrist_roll", "y", 0.0, 0.08)]
masses = [3.0, 2.5, 2.0, 0.8, 0.6, 0.4]
radius = [0.06, 0.05, 0.045, 0.04, 0.035, 0.03]
effort = [150, 150, 80, 30, 30, 20]
out = ['<?xml version="1.0"?>', '<robot name="my_arm">', '<link name="base"/>']
parent = "base"; z_off = 0.05
for i, (name, axis, _, length) in enumerate(L):
    child = f"link{i+1}"
    ax = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}[axis]
    out.append(f'<joint name="{name}" type="revolute"><origin xyz="0 0 {z_off}"/><parent link="{parent}"/><child link="{child}"/><axis xyz="{ax}"/><limit lower="-3.14" upper="3.14" effort="{effort[i]}" velocity="3.0"/></joint>')
    m, r = masses[i], radius[i]
    ixx = m * (3 * r**2 + length**2) / 12; izz = m * r**2 / 2
    out.append(f'<link name="{child}"><inertial><origin xyz="0 0 {length/2}"/><mass value="{m}"/><inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{ixx:.6g}" iyz="0" izz="{izz:.6g}"/></inertial>')
    for tag in ("collision", "visual"):
        out.append(f'<{tag}><origin xyz="0 0 {length/2}"/><geometry><cylinder radius="{r}" length="{length}"/></geometry></{tag}>')
        for z in (0.0, length):
            out.append(f'<{tag}><origin xyz="0 0 {z}"/><geometry><sphere radius="{r}"/></geometry></{tag}>')
    out.append('</link>')
    parent = child; z_off = length
out.append(f'<joint name="tool_joint" type="fixed"><origin xyz="0 0 {z_off}"/><parent link="{parent}"/><child link="tool"/></joint>')
out.append('<link name="tool"/>')
out.append('</robot>')
open(__import__('pathlib').Path(__file__).with_name('my_arm.urdf'), 'w').write("\n".join(out) + "\n")
