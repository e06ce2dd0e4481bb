"""The logs' message helpers: the JSON channels' schemas and texts, scene lines and spheres.

The JSON channels are the ones written once (``/reference``, ``/episode``); the per-step ones are
protobuf (:mod:`amex.log.flat_proto`). :func:`value_schema` still names the kinds of
``/method``'s values (:mod:`amex.log.method_topic`).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import fields
from typing import Any

import foxglove
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

from amex.core import palette
from amex.log.frames import IDENTITY, WORLD_FRAME, vec
from amex.sim.metrics import EpisodeResult

NUM = "%.9g"  # JSON number format of /reference (9 significant digits)


def color(hex_color: str, alpha: float = 1.0) -> Color:
    """A palette colour (``#rrggbb``, :mod:`amex.core.palette`) as Foxglove's Color."""
    r, g, b, a = palette.rgba(hex_color, alpha)
    return Color(r=r, g=g, b=b, a=a)


#: The scene's colours, from the palette: the goal gold, the obstacle black, the reference red.
GOAL_COLOR = color(palette.GOAL_COLOR, 0.35)
GOAL_DOT_COLOR = color(palette.GOAL_COLOR)
OBSTACLE_COLOR = color(palette.OBSTACLE_COLOR, 0.6)
REFERENCE_COLOR = color(palette.REFERENCE_COLOR)


def path_color(method: str) -> Color:
    """The executed TCP path of ``method``: its colour."""
    return color(palette.method_color(method))


def plan_color(method: str) -> Color:
    """The current plan of ``method``: its colour, lighter."""
    return color(palette.lighter(palette.method_color(method)))


def number_array(n: int | None = None) -> dict[str, Any]:
    """Schema of an array of numbers (of length ``n`` if given)."""
    schema: dict[str, Any] = {"type": "array", "items": {"type": "number"}}
    if n is not None:
        schema.update(minItems=n, maxItems=n)
    return schema


def value_schema(value: Any) -> dict[str, Any] | None:
    """The schema of one JSON value as viewers accept it; None for null or nested lists."""
    if isinstance(value, bool):
        return {"type": "boolean"}
    if isinstance(value, (int, float, np.integer, np.floating)):
        return {"type": "number"}
    if isinstance(value, str):
        return {"type": "string"}
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return number_array()
        return None
    return None


def object_schema(title: str, values: dict[str, Any]) -> dict[str, Any]:
    """Schema of a JSON object like ``values`` (keys whose values fit no schema are left out)."""
    props = {k: sch for k, v in values.items() if (sch := value_schema(v)) is not None}
    return {"title": title, "type": "object", "properties": props}


def episode_schema() -> dict[str, Any]:
    """``/episode``: the time, ``status`` and every column of an ``EpisodeResult``."""
    types = {"int": "number", "float": "number", "bool": "boolean", "str": "string"}
    props: dict[str, Any] = {"t": {"type": "number"}, "status": {"type": "string"}}
    for f in fields(EpisodeResult):
        props[f.name] = {"type": types[f.type if isinstance(f.type, str) else f.type.__name__]}
    return {"title": "amex.EpisodeResult", "type": "object", "properties": props}


def reference_schema(m: int) -> dict[str, Any]:
    """``/reference``: the plan as an array of samples (time, TCP position, the rest of y)."""
    sample = {
        "type": "object",
        "properties": {
            "t": {"type": "number"},
            "position": number_array(3),
            "axis": number_array(m - 3),
        },
    }
    return {
        "title": "amex.ReferencePlan",
        "type": "object",
        "properties": {
            "dt": {"type": "number"},
            "duration": {"type": "number"},
            "samples": {"type": "array", "items": sample},
        },
    }


def reference_json(y: np.ndarray, dt: float, duration: float) -> bytes:
    """The ``/reference`` message of a plan ``y`` (N + 1, m) sampled every ``dt`` [s].

    One %-format over all samples: ``{"t":k*dt,"position":[...],"axis":[...]}`` each.
    """
    rows = np.asarray(y, dtype=float)
    n, m = rows.shape
    times = [k * dt for k in range(n)]
    values = np.column_stack([np.array(times, dtype=float), rows]).ravel().tolist()
    sample = (
        '{"t":' + NUM + ',"position":[' + ",".join([NUM] * min(m, 3)) + '],"axis":['
        + ",".join([NUM] * max(m - 3, 0)) + "]}"
    )  # fmt: skip
    samples = ",".join([sample] * n) % tuple(values)
    text = f'{{"dt":{float(dt)!r},"duration":{float(duration)!r},"samples":[{samples}]}}'
    return text.encode()


def json_schemas(m: int = 6) -> dict[str, dict[str, Any]]:
    """The JSON channels and their schemas (task space of ``m``): ``/reference``, ``/episode``.

    The per-step channels are protobuf (:mod:`amex.log.flat_proto`, :mod:`amex.log.method_topic`).
    """
    return {"/reference": reference_schema(m), "/episode": episode_schema()}


@functools.lru_cache(maxsize=16)
def json_channel_schemas(m: int = 6) -> dict[str, foxglove.Schema]:
    """:func:`json_schemas` as the SDK's schema records, made once per ``m``.

    What ``foxglove.Channel`` makes of a dict schema (``jsonschema``, its ``title`` as the name,
    its ``json.dumps``), which it would otherwise encode again for every log.
    """
    return {
        topic: foxglove.Schema(
            name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode("utf-8")
        )
        for topic, schema in json_schemas(m).items()
    }


def viewer_schema_problems(schema: Any, where: str = "schema") -> list[str]:
    """What Foxglove (1.48 and Lichtblick) would reject in a JSON channel's schema; [] if none.

    Their rule (``parseJsonSchema`` of ``@foxglove/mcap-support``): the root and every nested
    object has ``"type": "object"`` and ``properties``; each property is a boolean, a string
    (optionally base64), a number or integer, an object (same rule), or an array whose ``items``
    is one of those scalars or an object (no arrays of arrays, no ``null``, no type lists); a
    ``oneOf`` is allowed only of numeric ``const`` alternatives.
    """
    if not isinstance(schema, dict) or schema.get("type") != "object":
        return [f'{where}: "type" must be "object"']
    props = schema.get("properties")
    if not isinstance(props, dict):
        return [f'{where}: an object needs "properties"']
    problems: list[str] = []
    for name, prop in props.items():
        path = f"{where}.{name}"
        if not isinstance(prop, dict):
            problems.append(f"{path}: not a schema")
            continue
        if "oneOf" in prop:
            alternatives = prop["oneOf"]
            if not (isinstance(alternatives, list) and all(
                    isinstance(a, dict) and isinstance(a.get("const"), (int, float))
                    for a in alternatives)):  # fmt: skip
                problems.append(f"{path}: oneOf alternatives must have number values")
            continue
        kind = prop.get("type")
        if kind in ("boolean", "number", "integer"):
            continue
        if kind == "string":
            if prop.get("contentEncoding") not in (None, "base64"):
                problems.append(f"{path}: unsupported contentEncoding")
        elif kind == "object":
            problems += viewer_schema_problems(prop, path)
        elif kind == "array":
            items = prop.get("items")
            if not isinstance(items, dict):
                problems.append(f'{path}: an array needs scalar or object "items"')
                continue
            item_kind = items.get("type")
            if item_kind == "object":
                problems += viewer_schema_problems(items, path + "[]")
            elif item_kind not in ("boolean", "string", "number", "integer"):
                problems.append(f'{path}: an array needs scalar or object "items"')
            elif item_kind == "string" and items.get("contentEncoding") is not None:
                problems.append(f"{path}[]: no contentEncoding in array items")
        else:
            problems.append(f"{path}: unsupported type {kind!r}")
    return problems


def metadata_record(values: dict[str, Any]) -> dict[str, str]:
    """An MCAP metadata record of ``values``: each key's value as a JSON text (:func:`jsonable`)."""
    return {str(k): json_text(v) for k, v in values.items()}


_TEXT = json.encoder.encode_basestring_ascii  # what json.dumps writes for a str


def json_text(value: Any) -> str:
    """``json.dumps(jsonable(value))``, its text: a number, a flag, a text or None directly.

    Those four are written as ``json.dumps`` writes them (``repr`` of a finite float or an int,
    its ASCII escapes of a text), without its call (~2 us each, ~40 in an episode's outcome).
    """
    kind = type(value)
    if kind is float:
        return float.__repr__(value) if math.isfinite(value) else "null"
    if kind is str:
        return _TEXT(value)
    if kind is bool:
        return "true" if value else "false"
    if kind is int:
        return int.__repr__(value)
    if value is None:
        return "null"
    return json.dumps(jsonable(value))


def jsonable(value: Any) -> Any:
    """Numbers stay numbers (non-finite -> null), arrays become lists, None stays null."""
    kind = type(value)
    if kind is float:  # the common types first, without the isinstance chain
        return value if math.isfinite(value) else None
    if kind is str or kind is int or kind is bool:
        return value
    if kind is list:
        return [jsonable(v) for v in value]
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


def point_rows(k: int, max_points: int) -> np.ndarray | None:
    """The rows :func:`points` keeps of k: at most ``max_points``, evenly strided; None: all."""
    if k <= max_points:
        return None
    # the steps are (k - 1) / (max_points - 1) > 1 apart: their roundings differ, so the rows
    # are distinct and increasing without np.unique (~20 us more; a plan's length changes often)
    return np.linspace(0, k - 1, max_points).round().astype(int)


def points(xyz: np.ndarray, max_points: int) -> list[Point3]:
    """At most ``max_points`` evenly strided points of ``xyz`` (k, 3), always with the last one."""
    rows = point_rows(len(xyz), max_points)
    if rows is not None:
        xyz = xyz[rows]
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
