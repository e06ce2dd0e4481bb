"""The logs' message helpers: JSON number templates and schemas, scene lines and spheres.

The per-step JSON channels are formatted from %-templates (``"%.9g"`` numbers, about 0.4 us each
here: ``json.dumps`` of the same floats costs 3x more); non-finite numbers become ``null``.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
from foxglove.messages import (
    Color,
    LinePrimitive,
    Point3,
    Pose,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    Timestamp,
    Vector3,
)

from amex.log.frames import IDENTITY, WORLD_FRAME, vec

NUM = "%.9g"  # JSON number format of the per-step channels (9 significant digits)
GOAL_COLOR = Color(r=0.1, g=0.75, b=0.2, a=0.35)
GOAL_DOT_COLOR = Color(r=0.1, g=0.6, b=0.1, a=1.0)
OBSTACLE_COLOR = Color(r=0.85, g=0.15, b=0.1, a=0.6)
PATH_COLOR = Color(r=0.1, g=0.35, b=0.95, a=1.0)
PLAN_COLOR = Color(r=1.0, g=0.55, b=0.0, a=1.0)
REFERENCE_COLOR = Color(r=0.45, g=0.45, b=0.45, a=1.0)


def json_template(fields: list[tuple[str, int]]) -> str:
    """A %-format JSON object of numbers: ``[("t", 0), ("q", 7)]`` -> ``{"t":%g,"q":[%g,...]}``."""
    parts = []
    for key, n in fields:
        value = NUM if n == 0 else "[" + ",".join([NUM] * n) + "]"
        parts.append(f'"{key}":{value}')
    return "{" + ",".join(parts) + "}"


def number_schema(title: str, fields: dict[str, int | str]) -> dict[str, Any]:
    """A JSON schema of an object of numbers (0) and number arrays (length n); str: a type."""
    props: dict[str, Any] = {}
    for key, n in fields.items():
        if isinstance(n, str):
            props[key] = {"type": n}
        elif n == 0:
            props[key] = {"type": "number"}
        else:
            props[key] = {
                "type": "array",
                "items": {"type": "number"},
                "minItems": n,
                "maxItems": n,
            }
    return {"title": title, "type": "object", "properties": props}


def json_schemas(n: int) -> dict[str, dict[str, Any]]:
    """The JSON channels and their schemas (``n`` joints)."""
    return {
        "/tcp": number_schema(
            "amex.Tcp",
            {"t": 0, "position": 3, "axis": 3, "velocity": 3, "distance_to_goal": 0},
        ),
        "/goal": number_schema("amex.Goal", {"t": 0, "position": 3, "distance": 0}),
        "/command": number_schema(
            "amex.Command", {"t": 0, "y_star": 6, "yd_star": 6, "q_star": n, "qd_star": n}
        ),
        "/method": {
            "title": "amex.MethodInternals",
            "type": "object",
            "properties": {"t": {"type": "number"}},
        },
        "/reference": number_schema("amex.ReferencePlan", {"dt": 0, "duration": 0, "y": "array"}),
        "/episode": number_schema("amex.EpisodeResult", {"t": 0, "status": "string"}),
    }


def jsonable(value: Any) -> Any:
    """Numbers stay numbers (non-finite -> null), arrays become lists, None stays null."""
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    return str(value)


_ENCODER = json.JSONEncoder(allow_nan=False, separators=(",", ":"))


def dumps(obj: dict[str, Any]) -> bytes:
    """Strict JSON (no NaN): the fast path, or a sanitized copy when something is not finite."""
    try:
        return _ENCODER.encode(obj).encode()
    except (ValueError, TypeError):
        return _ENCODER.encode(jsonable(obj)).encode()


def points(xyz: np.ndarray, max_points: int) -> list[Point3]:
    """At most ``max_points`` evenly strided points of ``xyz`` (k, 3), always with the last one."""
    k = len(xyz)
    if k > max_points:
        idx = np.unique(np.linspace(0, k - 1, max_points).round().astype(int))
        xyz = xyz[idx]
    return [Point3(x=x, y=y, z=z) for x, y, z in np.asarray(xyz, dtype=float)[:, :3].tolist()]


def line_update(
    stamp: Timestamp, entity: str, points: list[Point3], color: Color, thickness: float
) -> SceneUpdate:
    """A scene update with one entity ``entity``: a line strip (thickness in pixels)."""
    line = LinePrimitive(points=points, color=color, thickness=thickness, scale_invariant=True)
    return SceneUpdate(
        entities=[SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id=entity, lines=[line])]
    )


def sphere(center: Any, diameter: float, color: Color) -> SpherePrimitive:
    """A sphere primitive of ``diameter`` [m] at ``center``."""
    return SpherePrimitive(
        pose=Pose(position=vec(center), orientation=IDENTITY),
        size=Vector3(x=diameter, y=diameter, z=diameter),
        color=color,
    )
