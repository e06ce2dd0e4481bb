"""Collision capsules of an arm: merged from URDF primitives, or fitted to mesh vertices.

The controller's distances (coal), the planner's batched kinematics and MuJoCo's contacts all use
one set of capsules per robot. Two sources:

* URDF primitives (the Panda's ``panda_collision.urdf``, the generated ``chain7``): a cylinder
  with a sphere of the same radius on each end cap *is* a capsule, so such triples are merged
  (:func:`merge_primitives`); lone spheres stay spheres (capsules of half length 0) and a lone
  cylinder becomes its enclosing capsule.
* Meshes (the UR arms, most vendors' URDFs): :func:`fit_capsule` encloses the vertices of each
  collision mesh in one capsule. The axis is the vertices' principal direction; the radius and
  the axis' position are the smallest circle enclosing the vertices projected onto the plane
  normal to the axis (Welzl's algorithm); the caps are then pulled in as far as the vertices allow
  (a vertex at axial coordinate t and radial distance rho <= r is covered by the end sphere at t_1
  as long as ``t - t_1 <= sqrt(r^2 - rho^2)``). The result contains every vertex.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin


@dataclass(frozen=True)
class Capsule:
    """A capsule (a sphere if ``half_length`` is 0) rigidly attached to a joint frame.

    Attributes:
        name: name of the geometry it came from.
        joint_id: Pinocchio joint the shape moves with (0: the fixed base).
        placement: shape frame in the joint frame; the capsule's axis is its z-axis.
        radius: [m].
        half_length: half the length of the axis segment [m].
        fitted: fitted to a mesh or box (False: the URDF's own primitive shape).
    """

    name: str
    joint_id: int
    placement: pin.SE3
    radius: float
    half_length: float
    fitted: bool = False

    def segment(self) -> tuple[np.ndarray, np.ndarray]:
        """End points of the axis segment in the joint frame, shapes (3,) [m]."""
        M = self.placement
        return (
            M.act(np.array([0.0, 0.0, -self.half_length])),
            M.act(np.array([0.0, 0.0, self.half_length])),
        )


def merge_primitives(geom_model: pin.GeometryModel) -> tuple[list[Capsule], list[int]]:
    """Capsules from the cylinders and spheres of ``geom_model``; also the indices not used.

    A cylinder with two spheres of its radius at its end caps becomes one capsule (the same
    shape, a third of the distance queries); a cylinder without them becomes its enclosing
    capsule; remaining spheres stay spheres. Other shapes (meshes, boxes) are left to
    :func:`fit_capsule` and returned as the second value.
    """
    objects = list(geom_model.geometryObjects)
    used: set[int] = set()
    capsules: list[Capsule] = []
    for i, obj in enumerate(objects):
        geo = obj.geometry
        if not isinstance(geo, coal.Cylinder):
            continue
        M = obj.placement
        ends = [M.act(np.array([0.0, 0.0, s * geo.halfLength])) for s in (-1.0, 1.0)]
        caps = []
        for j, other in enumerate(objects):
            if j in used or j == i or other.parentJoint != obj.parentJoint:
                continue
            if not isinstance(other.geometry, coal.Sphere):
                continue
            if abs(other.geometry.radius - geo.radius) > 1e-9:
                continue
            if any(np.linalg.norm(other.placement.translation - e) < 1e-3 for e in ends):
                caps.append(j)
        if len(caps) == 2:
            used.update(caps)
        used.add(i)
        half = geo.halfLength if len(caps) == 2 else geo.halfLength + geo.radius
        capsules.append(Capsule(obj.name, obj.parentJoint, M, float(geo.radius), float(half)))
    for j, obj in enumerate(objects):
        if j in used:
            continue
        if isinstance(obj.geometry, coal.Sphere):
            used.add(j)
            radius = float(obj.geometry.radius)
            capsules.append(Capsule(obj.name, obj.parentJoint, obj.placement, radius, 0.0))
        elif isinstance(obj.geometry, coal.Capsule):
            used.add(j)
            geo = obj.geometry
            capsules.append(
                Capsule(obj.name, obj.parentJoint, obj.placement, geo.radius, geo.halfLength)
            )
    rest = [j for j in range(len(objects)) if j not in used]
    return capsules, rest


def shape_vertices(obj: pin.GeometryObject) -> np.ndarray:
    """Points whose enclosing capsule encloses the shape, in the joint frame, shape (n, 3) [m].

    Meshes give their vertices (coal loads them with the URDF's scale applied), boxes their 8
    corners.

    Raises:
        ValueError: for a shape without vertices (an empty mesh) or of another kind.
    """
    geo = obj.geometry
    if isinstance(geo, coal.Box):
        half = np.asarray(geo.halfSide, dtype=float)
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        local = signs * half
    elif hasattr(geo, "vertices"):
        local = np.asarray(geo.vertices(), dtype=float).reshape(-1, 3)
    else:
        raise ValueError(f"collision shape {obj.name!r} of type {type(geo).__name__}")
    if len(local) == 0 or not np.isfinite(local).all():
        raise ValueError(f"collision shape {obj.name!r} has no finite vertices")
    M = obj.placement
    return local @ M.rotation.T + M.translation


def _circle_two(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    c = 0.5 * (a + b)
    return c, float(np.linalg.norm(a - c))


def _circle_three(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, float]:
    """Circumcircle of a triangle in 2-D (the widest pair's circle if it is degenerate)."""
    bx, by = b - a
    cx, cy = c - a
    d = 2.0 * (bx * cy - by * cx)
    if abs(d) < 1e-18:
        pairs = [_circle_two(a, b), _circle_two(a, c), _circle_two(b, c)]
        return max(pairs, key=lambda p: p[1])
    b2, c2 = bx * bx + by * by, cx * cx + cy * cy
    centre = a + np.array([(cy * b2 - by * c2) / d, (bx * c2 - cx * b2) / d])
    return centre, float(np.linalg.norm(a - centre))


def enclosing_circle(points: np.ndarray, seed: int = 0) -> tuple[np.ndarray, float]:
    """Smallest circle containing 2-D ``points`` (n, 2): centre (2,), radius (Welzl, iterative).

    Expected O(n) after a seeded shuffle, so the result is deterministic.
    """
    pts = np.asarray(points, dtype=float)
    pts = pts[np.random.default_rng(seed).permutation(len(pts))]
    tol = 1e-12
    centre, radius = pts[0], 0.0
    for i in range(1, len(pts)):
        if np.linalg.norm(pts[i] - centre) <= radius + tol:
            continue
        centre, radius = pts[i], 0.0
        for j in range(i):
            if np.linalg.norm(pts[j] - centre) <= radius + tol:
                continue
            centre, radius = _circle_two(pts[i], pts[j])
            for k in range(j):
                if np.linalg.norm(pts[k] - centre) > radius + tol:
                    centre, radius = _circle_three(pts[i], pts[j], pts[k])
    return centre, radius


def fit_capsule(vertices: np.ndarray) -> tuple[pin.SE3, float, float]:
    """An enclosing capsule of ``vertices`` (n, 3) [m] (module notes).

    Returns:
        The capsule frame (z along the axis, origin at the segment's middle), the radius and the
        half length [m]. Every vertex lies inside the capsule (to 1e-9 m).
    """
    P = np.unique(np.asarray(vertices, dtype=float), axis=0)
    mean = P.mean(axis=0)
    if len(P) < 3:  # a point or a segment
        axis = P[-1] - P[0] if len(P) == 2 else np.array([0.0, 0.0, 1.0])
        axis = axis / max(np.linalg.norm(axis), 1e-12)
    else:
        _, _, Vt = np.linalg.svd(P - mean, full_matrices=False)
        axis = Vt[0]
    axis = axis * (1.0 if axis[np.argmax(np.abs(axis))] > 0 else -1.0)  # a fixed sign
    R = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), axis).matrix()
    local = (P - mean) @ R  # coordinates in a frame whose z is the axis
    centre_xy, radius = enclosing_circle(local[:, :2])
    radius = max(radius, 1e-6)
    radial = np.linalg.norm(local[:, :2] - centre_xy, axis=1)
    reach = np.sqrt(np.maximum(radius * radius - radial * radial, 0.0))
    t_lo = float(np.min(local[:, 2] + reach))  # the lower end sphere's centre, as high as allowed
    t_hi = float(np.max(local[:, 2] - reach))
    if t_hi < t_lo:  # the vertices fit in one sphere of this radius: a sphere on the axis
        t_lo = t_hi = 0.5 * (t_lo + t_hi)
        z = local[:, 2] - t_lo
        radius = float(np.sqrt(np.max(radial * radial + z * z)))
    origin_local = np.array([centre_xy[0], centre_xy[1], 0.5 * (t_lo + t_hi)])
    frame = pin.SE3(R, mean + R @ origin_local)
    return frame, float(radius), 0.5 * (t_hi - t_lo)


def fit_capsules(geom_model: pin.GeometryModel, indices: list[int]) -> list[Capsule]:
    """One fitted capsule per shape of ``geom_model`` listed in ``indices`` (meshes, boxes).

    Raises:
        ValueError: for a shape without usable vertices.
    """
    capsules = []
    for j in indices:
        obj = geom_model.geometryObjects[j]
        frame, radius, half = fit_capsule(shape_vertices(obj))
        capsules.append(Capsule(obj.name, obj.parentJoint, frame, radius, half, fitted=True))
    return capsules


def capsule_volume(radius: float, half_length: float) -> float:
    """Volume of a capsule [m^3]."""
    return math.pi * radius**2 * (2.0 * half_length) + 4.0 / 3.0 * math.pi * radius**3


def segment_distances(capsule: Capsule, points: np.ndarray) -> np.ndarray:
    """Distance of each point (n, 3) in the joint frame to the capsule's axis segment [m]."""
    a, b = capsule.segment()
    ab = b - a
    denom = float(ab @ ab)
    u = np.zeros(len(points)) if denom == 0.0 else np.clip((points - a) @ ab / denom, 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * ab), axis=1)
