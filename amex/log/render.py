"""MuJoCo offscreen rendering of a logged robot: the arm, spheres and paths, headless.

Used by ``amex-log video`` and Fig. 4. The arm is compiled by MuJoCo from the URDF a log names
(its ``robot`` metadata), not from a robot catalogue, so any logged robot renders. By default it is
drawn with the URDF's visual meshes (:func:`arm_model`, ``geometry="visual"``): MuJoCo reads no
Collada, so each visual mesh is read with trimesh (pycollada for ``.dae``), its parts grouped by
their material colour and added to the link's body as MuJoCo meshes (the Panda: white links, dark
joint rings); URDF boxes, cylinders and spheres become MuJoCo's own. The collision shapes stay in
the model for the kinematics but in geom group 3, which MuJoCo does not draw by default;
``geometry="collision"`` draws them instead (translucent capsules, the old look). Mesh references
are resolved like :func:`amex.robot.meshes.resolve_mesh`; a visual whose mesh is missing or
unreadable is left out, and a robot with no visual left is drawn with its collision shapes.
Spheres and paths are added to the scene per frame (:class:`SceneDrawer`), so nothing but the arm
lives in the model.

Framing: :func:`frame_points` gives the points the camera must see, the arm's bodies at the
configurations shown included, for :func:`aim_camera`; :func:`split_viewport` and
:func:`draw_caption` keep captions in bands above and below the scene, off the robot.

Headless OpenGL: ``MUJOCO_GL`` if set (``egl`` or ``osmesa``), else EGL, else OSMesa; Debian's
``libegl1``, ``libegl-mesa0`` and ``libgl1-mesa-dri`` provide EGL without a GPU (Mesa's software
rasterizer). :func:`gl_context` says which backends failed and why.
"""

from __future__ import annotations

import functools
import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from amex.core.errors import RenderError
from amex.robot.meshes import resolve_mesh

MESH_FORMATS = (".stl", ".obj", ".msh")  # what MuJoCo's compiler reads
GL_HELP = "install Debian's libegl1 libegl-mesa0 libgl1-mesa-dri (make render-deps)"
GEOMETRIES = ("visual", "collision")
VISUAL_GROUP, COLLISION_GROUP = 1, 3  # MuJoCo draws groups 0-2 by default
CAPSULE_RGB = (0.75, 0.75, 0.78)
DEFAULT_RGBA = (0.85, 0.85, 0.87, 1.0)  # a visual without a colour of its own


def gl_context(width: int, height: int) -> Any:
    """A current offscreen OpenGL context of ``width`` x ``height`` pixels (see module notes).

    Raises:
        RenderError: no backend works; the message lists why each failed.
    """
    errors = []
    wanted = os.environ.get("MUJOCO_GL", "").lower()
    for backend in dict.fromkeys(b for b in (wanted, "egl", "osmesa") if b in ("egl", "osmesa")):
        try:
            if backend == "egl":
                from mujoco.egl import GLContext
            else:
                from mujoco.osmesa import GLContext  # type: ignore[no-redef]
            context = GLContext(width, height)
            context.make_current()
            return context
        except Exception as e:  # no libEGL/libOSMesa, no device, a platform clash, ...
            errors.append(f"{backend}: {type(e).__name__}: {str(e)[:80]}")
    raise RenderError(f"no headless OpenGL here ({'; '.join(errors)}); {GL_HELP}")


def _collision_urdf(urdf_path: Path, package_dirs: Sequence[str] = ()) -> str:
    """The URDF without visuals, every collision mesh an absolute path MuJoCo can read."""
    try:
        root = ET.fromstring(urdf_path.read_text())
    except (OSError, ET.ParseError) as e:
        raise RenderError(f"cannot read the robot description {urdf_path}: {e}") from e
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        for collision in link.findall("collision"):
            for mesh in collision.iter("mesh"):
                path = resolve_mesh(mesh.get("filename", ""), urdf_path, package_dirs)
                if path is None or path.suffix.lower() not in MESH_FORMATS:
                    link.remove(collision)
                    break
                mesh.set("filename", str(path))
    return ET.tostring(root, encoding="unicode")


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


def _add_visuals(spec: Any, urdf_path: Path, package_dirs: Sequence[str], alpha: float) -> int:
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


def arm_model(
    urdf_path: str,
    samples: int = 4,
    alpha: float | None = None,
    package_dirs: Sequence[str] = (),
    *,
    geometry: str = "visual",
) -> Any:
    """The arm as a MuJoCo model for drawing (no obstacles, no actuation; see module notes).

    Args:
        urdf_path: the robot's URDF.
        samples: multisampling of the offscreen buffer (0 renders a video frame ~3x faster in
            software, with jagged edges).
        alpha: opacity of the arm (default: opaque meshes, translucent capsules).
        package_dirs: where ``package://`` mesh URLs resolve first.
        geometry: ``"visual"`` (the URDF's visual meshes) or ``"collision"`` (its collision
            shapes, the controller's capsules for the Panda).
    """
    import mujoco

    if geometry not in GEOMETRIES:
        raise RenderError(f"invalid geometry={geometry!r}; valid: {', '.join(GEOMETRIES)}")
    text = _collision_urdf(Path(urdf_path), package_dirs)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(text)
    try:
        spec = mujoco.MjSpec.from_file(f.name)
        visuals = 0
        if geometry == "visual":
            visuals = _add_visuals(
                spec, Path(urdf_path), package_dirs, 1.0 if alpha is None else alpha
            )
        capsule_alpha = 0.5 if alpha is None else alpha
        for geom in spec.geoms:
            if geom.group != VISUAL_GROUP or not visuals:
                geom.rgba = [*CAPSULE_RGB, capsule_alpha]
                geom.group = COLLISION_GROUP if visuals else 0
        spec.compiler.discardvisual = False  # else the URDF importer drops the sky texture
        spec.add_texture(  # a light sky behind the scene instead of black
            name="amex_sky",
            type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
            builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
            rgb1=[0.95, 0.96, 0.98],
            rgb2=[0.55, 0.62, 0.72],
            width=64,
            height=384,
        )
        model = spec.compile()
    except ValueError as e:
        raise RenderError(f"MuJoCo cannot compile {urdf_path} for drawing: {e}") from e
    finally:
        os.unlink(f.name)
    model.vis.quality.offsamples = samples
    model.vis.headlight.ambient[:] = 0.45
    model.vis.headlight.diffuse[:] = 0.5
    return model


def joint_addresses(model: Any, joint_names: list[str]) -> np.ndarray:
    """``qpos`` index of each named joint (-1 if the model lacks it), shape (n,)."""
    import mujoco

    addresses = []
    for name in joint_names:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        addresses.append(int(model.jnt_qposadr[jid]) if jid >= 0 else -1)
    return np.array(addresses, dtype=int)


class SceneDrawer:
    """Adds spheres, paths and a floor to a ``mujoco.MjvScene`` after ``mjv_updateScene``."""

    def __init__(self, scene: Any) -> None:
        self.scene = scene

    def _geom(self) -> Any:
        if self.scene.ngeom >= self.scene.maxgeom:
            return None
        self.scene.ngeom += 1
        return self.scene.geoms[self.scene.ngeom - 1]

    def sphere(self, center: np.ndarray, radius: float, rgba: tuple) -> None:
        """A sphere of ``radius`` [m] at ``center``."""
        import mujoco

        geom = self._geom()
        if geom is not None:
            mujoco.mjv_initGeom(
                geom,
                mujoco.mjtGeom.mjGEOM_SPHERE,
                np.full(3, radius),
                np.asarray(center, dtype=float),
                np.eye(3).ravel(),
                np.asarray(rgba, dtype=np.float32),
            )

    def path(self, points: np.ndarray, rgba: tuple, width: float, max_segments: int = 150) -> None:
        """A polyline through ``points`` (k, 3): lines ``width`` pixels wide.

        GL lines, not capsules: a capsule per segment costs ~0.2 ms to rasterize in software,
        a line almost nothing.
        """
        import mujoco

        points = np.asarray(points, dtype=float).reshape(-1, 3)
        points = points[np.isfinite(points).all(axis=1)]
        if len(points) < 2:
            return
        step = max(1, len(points) // max_segments)
        pts = np.concatenate([points[::step], points[-1:]])
        color = np.asarray(rgba, dtype=np.float32)
        for a, b in zip(pts[:-1], pts[1:], strict=True):
            if np.allclose(a, b):
                continue
            geom = self._geom()
            if geom is None:
                return
            mujoco.mjv_initGeom(
                geom, mujoco.mjtGeom.mjGEOM_LINE, np.zeros(3), np.zeros(3), np.eye(3).ravel(), color
            )
            mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, width, a, b)

    def floor(self, center_xy: np.ndarray, half: float) -> None:
        """A light floor at z = 0 (the arm's model has none) so that dark objects stand out."""
        import mujoco

        geom = self._geom()
        if geom is not None:
            mujoco.mjv_initGeom(
                geom,
                mujoco.mjtGeom.mjGEOM_BOX,
                np.array([half, half, 0.002]),
                np.array([center_xy[0], center_xy[1], -0.002]),
                np.eye(3).ravel(),
                np.array([0.86, 0.86, 0.84, 1.0], dtype=np.float32),
            )


def arm_points(model: Any, addresses: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Positions of every body of the arm at each configuration of ``q`` (k, joints), (k*b, 3)."""
    import mujoco

    data = mujoco.MjData(model)
    valid = addresses >= 0
    points = []
    for row in np.asarray(q, dtype=float).reshape(-1, len(addresses)):
        data.qpos[addresses[valid]] = row[valid]
        mujoco.mj_kinematics(model, data)
        points.append(data.xpos.copy())
    return np.concatenate(points) if points else np.zeros((0, 3))


def aim_camera(
    camera: Any,
    points: np.ndarray,
    motion: np.ndarray,
    elevation: float = -35.0,
    margin: float = 1.7,
    fovy: float = 45.0,
) -> None:
    """Aim a free camera at the scene ``points`` (k, 3), looking across the ``motion``.

    The camera looks at the middle of the points horizontally at right angles to ``motion`` (the
    main direction of travel, e.g. start to goal), from the side away from the robot's base at
    the origin, so that the arm stands behind the paths; from ``elevation`` degrees (negative:
    from above), at the distance where ``margin`` times the points' bounding sphere fills the
    vertical field of view ``fovy`` [deg].
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.05)
    m = np.asarray(motion, dtype=float)[:2]
    side = np.array([m[1], -m[0]]) if np.linalg.norm(m) > 1e-9 else center[:2].copy()
    if side @ center[:2] < 0:
        side = -side
    camera.lookat[:] = center
    camera.distance = margin * radius / np.sin(np.radians(fovy / 2))
    camera.azimuth = float(np.degrees(np.arctan2(-side[1], -side[0])))
    camera.elevation = elevation


def frame_points(model: Any, addresses: np.ndarray, q: np.ndarray, every: int = 1) -> np.ndarray:
    """What a camera must see of the arm: its base and its bodies at the configurations ``q``.

    ``q`` (k, joints), every ``every``-th configuration; body origins only, so add a margin
    (:func:`aim_camera`'s ``margin``) for the links' own size. Shape (m, 3) [m].
    """
    q = np.asarray(q, dtype=float).reshape(-1, len(addresses))
    rows = q[:: max(1, int(every))]
    if len(q):
        rows = np.concatenate([rows, q[-1:]])
    return np.concatenate([np.zeros((1, 3)), arm_points(model, addresses, rows)])


BAND_RGB = (0.97, 0.97, 0.98)  # the caption bands' background


def split_viewport(viewport: Any, band: int) -> tuple[Any, Any, Any]:
    """``viewport`` as (scene, top band, bottom band), each band ``band`` pixels high.

    Captions go into the bands, never over the scene.
    """
    import mujoco

    left, bottom, width, height = viewport.left, viewport.bottom, viewport.width, viewport.height
    band = max(0, min(int(band), height // 3))
    scene = mujoco.MjrRect(left, bottom + band, width, height - 2 * band)
    top = mujoco.MjrRect(left, bottom + height - band, width, band)
    low = mujoco.MjrRect(left, bottom, width, band)
    return scene, top, low


def draw_caption(context: Any, rect: Any, text: str) -> None:
    """Fill the band ``rect`` and write one line of ``text`` in it (after ``mjr_render``)."""
    import mujoco

    mujoco.mjr_rectangle(rect, *BAND_RGB, 1.0)
    if text:
        font = mujoco.mjtFont.mjFONT_NORMAL
        mujoco.mjr_overlay(font, mujoco.mjtGridPos.mjGRID_LEFT, rect, text, "", context)
