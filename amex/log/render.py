"""MuJoCo offscreen rendering of a logged robot: the arm, spheres and paths, headless.

Used by ``amex-log video`` and Fig. 4. The arm is compiled by MuJoCo from the URDF a log names
(its ``robot`` metadata), not from a robot catalogue, so any logged robot renders. By default it is
drawn with the URDF's visual meshes (:func:`arm_model`, ``geometry="visual"``, read by
:mod:`amex.log.visuals`). The collision shapes stay in the model for the kinematics but in geom
group 3, which MuJoCo does not draw by default; ``geometry="collision"`` draws them instead
(translucent capsules, the old look); a robot with no visual left is drawn with its collision
shapes. Collision mesh references are resolved by :func:`amex.robot.meshes.resolve_mesh`.
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

import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from amex.core.errors import RenderError
from amex.log.visuals import VISUAL_GROUP, add_visuals
from amex.robot.meshes import resolve_mesh

MESH_FORMATS = (".stl", ".obj", ".msh")  # what MuJoCo's compiler reads
GL_HELP = "install Debian's libegl1 libegl-mesa0 libgl1-mesa-dri (make render-deps)"
GEOMETRIES = ("visual", "collision")
COLLISION_GROUP = 3  # MuJoCo draws groups 0-2 by default; the visuals are in group 1
CAPSULE_RGB = (0.75, 0.75, 0.78)


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
            visuals = add_visuals(
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
