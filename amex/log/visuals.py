"""The URDF's visual meshes as MuJoCo geoms, for drawing (:func:`amex.log.render.arm_model`).

MuJoCo reads no Collada, so each ``<visual>`` mesh is read with trimesh (pycollada for ``.dae``),
its parts grouped by their material colour and added to the link's body as MuJoCo meshes (the
Panda: white links, dark joint rings); URDF boxes, cylinders and spheres become MuJoCo's own.
Visual geoms are in group :data:`VISUAL_GROUP`, collide with nothing and weigh nothing. A visual
whose mesh is missing or unreadable is left out.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from amex.core.errors import RenderError
from amex.robot.meshes import resolve_mesh

VISUAL_GROUP = 1  # MuJoCo draws groups 0-2 by default
DEFAULT_RGBA = (0.85, 0.85, 0.87, 1.0)  # a visual without a colour of its own


def _rotation_rpy(rpy: Sequence[float]) -> np.ndarray:
    """URDF's roll-pitch-yaw as a rotation matrix, ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r, p, y = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _floats(text: str | None, default: Sequence[float]) -> list[float]:
    return [float(v) for v in text.split()] if text else list(default)


@functools.lru_cache(maxsize=64)
def mesh_parts(path: str, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> tuple[Any, ...]:
    """The parts of a mesh file by colour: ``((vertices (n, 3), faces (m, 3), rgba), ...)``.

    Read with trimesh (``.dae`` through pycollada, ``.stl``, ``.obj``, ...), every part placed by
    the file's own scene graph, parts of one colour merged; a part without a colour has None.

    Raises:
        RenderError: the file cannot be read as a mesh.
    """
    import warnings

    import trimesh

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene: Any = trimesh.load(path, force="scene")
    except Exception as e:  # trimesh and pycollada raise many types for a bad file
        raise RenderError(f"cannot read the mesh {path}: {type(e).__name__}: {e}") from e
    groups: dict[Any, list[tuple[np.ndarray, np.ndarray]]] = {}
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        mesh = scene.geometry.get(name)
        if mesh is None or not hasattr(mesh, "faces") or not len(mesh.faces):
            continue
        vertices = np.asarray(mesh.vertices, dtype=float) @ transform[:3, :3].T + transform[:3, 3]
        groups.setdefault(_mesh_rgba(mesh), []).append(
            (vertices * np.asarray(scale), np.asarray(mesh.faces, dtype=int))
        )
    parts = []
    for rgba, pieces in groups.items():
        offsets = np.cumsum([0] + [len(v) for v, _ in pieces])[:-1]
        vertices = np.concatenate([v for v, _ in pieces])
        faces = np.concatenate([f + o for (_, f), o in zip(pieces, offsets, strict=True)])
        parts.append((vertices, faces, rgba))
    return tuple(parts)


def _mesh_rgba(mesh: Any) -> tuple[float, float, float, float] | None:
    """A trimesh mesh's colour (its material's main colour, else its mean face colour)."""
    visual: Any = getattr(mesh, "visual", None)
    color: Any = None
    material = getattr(visual, "material", None)
    if material is not None and getattr(material, "main_color", None) is not None:
        color = np.array(material.main_color, dtype=float)
    elif getattr(visual, "kind", None) == "face":
        color = np.array(visual.face_colors, dtype=float).mean(axis=0)
    if color is None or len(color) < 3:
        return None
    rgba = (*(color[:3] / 255.0), 1.0)
    return tuple(round(float(c), 4) for c in rgba)  # type: ignore[return-value]


def _primitive(shape: Any) -> tuple[Any, list[float]] | None:
    """A URDF box, cylinder or sphere as MuJoCo's geom type and size (None: another shape)."""
    import mujoco

    if shape.tag == "box":
        return mujoco.mjtGeom.mjGEOM_BOX, [x / 2 for x in _floats(shape.get("size"), (0.1,) * 3)]
    if shape.tag == "cylinder":
        r, length = float(shape.get("radius", 0.05)), float(shape.get("length", 0.1))
        return mujoco.mjtGeom.mjGEOM_CYLINDER, [r, length / 2, 0.0]
    if shape.tag == "sphere":
        return mujoco.mjtGeom.mjGEOM_SPHERE, [float(shape.get("radius", 0.05)), 0.0, 0.0]
    return None


def add_visuals(spec: Any, urdf_path: Path, package_dirs: Sequence[str], alpha: float) -> int:
    """Add every URDF ``<visual>`` to the body of its link; the number of geoms added."""
    import mujoco

    root = ET.fromstring(urdf_path.read_text())
    materials: dict[str, list[float]] = {}
    for named in root.iter("material"):
        color = named.find("color")
        if named.get("name") and color is not None:
            materials[named.get("name", "")] = _floats(color.get("rgba"), DEFAULT_RGBA)
    added = 0
    for link in root.iter("link"):
        body = spec.body(link.get("name", ""))
        if body is None:
            continue
        for k, visual in enumerate(link.findall("visual")):
            origin = visual.find("origin")
            xyz = _floats(origin.get("xyz") if origin is not None else None, (0, 0, 0))
            R = _rotation_rpy(_floats(origin.get("rpy") if origin is not None else None, (0, 0, 0)))
            paint = visual.find("material")
            own: list[float] | None = None
            if paint is not None:
                tint = paint.find("color")
                own = (_floats(tint.get("rgba"), DEFAULT_RGBA) if tint is not None
                       else materials.get(paint.get("name", "")))  # fmt: skip
            geometry = visual.find("geometry")
            shape = geometry[0] if geometry is not None and len(geometry) else None
            if shape is None:
                continue
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, R.ravel())
            fallback = list(own or DEFAULT_RGBA)
            primitive = _primitive(shape)
            if primitive is not None:
                body.add_geom(type=primitive[0], size=primitive[1], pos=xyz, quat=quat,
                              rgba=[*fallback[:3], fallback[3] * alpha], contype=0,
                              conaffinity=0, group=VISUAL_GROUP, mass=0)  # fmt: skip
                added += 1
                continue
            if shape.tag != "mesh":
                continue
            path = resolve_mesh(shape.get("filename", ""), urdf_path, package_dirs)
            if path is None:
                continue
            scale = tuple(_floats(shape.get("scale"), (1.0, 1.0, 1.0))[:3])
            try:
                parts = mesh_parts(str(path), scale)  # type: ignore[arg-type]
            except RenderError:
                continue
            for j, (vertices, faces, rgba) in enumerate(parts):
                name = f"amex_visual_{link.get('name')}_{k}_{j}"
                mesh = spec.add_mesh(name=name)
                mesh.uservert = (vertices @ R.T + np.asarray(xyz)).ravel().tolist()
                mesh.userface = faces.ravel().tolist()
                mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
                part_rgba = list(rgba or fallback)
                body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name,
                              rgba=[*part_rgba[:3], part_rgba[3] * alpha], contype=0, conaffinity=0,
                              group=VISUAL_GROUP, mass=0)  # fmt: skip
                added += 1
    return added
