"""The scene topics' ``foxglove.SceneUpdate`` messages, protobuf-encoded without the SDK's objects.

A line of k points built as SDK objects costs ~0.7 us per point (CR's plan, 100 points every 5
steps, was ~15 us per outer step); the goal and obstacle spheres ~11 us per update. Here the
constant parts of each message (frame and entity ids, colours, sizes, thickness, a sphere's
orientation) are the SDK's own bytes, encoded once (:func:`line_encoding`,
:func:`sphere_encoding`), and what changes (the timestamp, the points, the sphere centres) is
written around them: points by the compiled :func:`encode_vectors` (zero coordinates omitted,
as proto3 writes no defaults), lengths as varints. The result equals the SDK's bytes for the
same message (tests/log/test_wire.py).

Wire layout (field numbers of the Foxglove schemas): ``SceneUpdate.entities`` (2) holds one
``SceneEntity``: ``timestamp`` (1), ``frame_id`` (2), ``id`` (3), then ``spheres`` (9) or
``lines`` (11). A ``LinePrimitive``'s ``points`` (5) sit between its ``thickness`` (3) and
``scale_invariant`` (4) and its ``color`` (6); a ``SpherePrimitive`` is ``pose`` (1: ``position``
(1), ``orientation`` (2)), ``size`` (2), ``color`` (3).
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
from foxglove.messages import (
    Color,
    LinePrimitive,
    Pose,
    SceneEntity,
    SpherePrimitive,
    Vector3,
)

from amex.log.frames import IDENTITY, WORLD_FRAME

_ENTITIES = b"\x12"  # SceneUpdate.entities (field 2)
_SPHERES = b"\x4a"  # SceneEntity.spheres (field 9)
_LINES = b"\x5a"  # SceneEntity.lines (field 11)
_POINT = 0x2A  # LinePrimitive.points (field 5)
_POSITION = 0x0A  # Pose.position (field 1)
_POSE = b"\x0a"  # SpherePrimitive.pose (field 1)


def varint(value: int) -> bytes:
    """``value`` >= 0 as a protobuf varint."""
    if value < 0x80:
        return bytes((value,))
    out = bytearray()
    while value >= 0x80:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def timestamp_field(ns: int) -> bytes:
    """Field 1 holding the ``google.protobuf.Timestamp`` of ``ns`` [ns] (zero fields omitted)."""
    seconds, nanos = divmod(ns, 1_000_000_000)
    body = (b"\x08" + varint(seconds) if seconds else b"") + (
        b"\x10" + varint(nanos) if nanos else b""
    )
    return b"\x0a" + varint(len(body)) + body


def _field(tag: bytes, body: bytes) -> bytes:
    return tag + varint(len(body)) + body


@numba.njit(cache=True)
def _write_vectors(xyz: np.ndarray, tag: int, out: np.ndarray) -> int:
    scratch = np.empty(1)
    raw = scratch.view(np.uint8)
    i = 0
    for r in range(xyz.shape[0]):
        size = 0
        for c in range(3):
            if xyz[r, c] != 0.0:
                size += 9
        out[i] = tag
        out[i + 1] = size
        i += 2
        for c in range(3):
            value = xyz[r, c]
            if value != 0.0:
                out[i] = 0x09 + 8 * c
                scratch[0] = value
                for b in range(8):
                    out[i + 1 + b] = raw[b]
                i += 9
    return i


def encode_vectors(xyz: np.ndarray, tag: int) -> bytes:
    """Each row of ``xyz`` (k, >= 3) as a field ``tag`` holding a Point3/Vector3 (x, y, z)."""
    points = np.ascontiguousarray(np.asarray(xyz, dtype=float)[:, :3])
    out = np.empty(29 * len(points), dtype=np.uint8)
    return out[: _write_vectors(points, tag, out)].tobytes()


class LineEncoding(NamedTuple):
    """The constant parts of a line entity's update (:func:`line_encoding`)."""

    entity: bytes  # SceneEntity's frame_id and id
    head: bytes  # LinePrimitive's fields before its points (thickness, scale_invariant)
    tail: bytes  # and after them (color)


def line_encoding(entity: str, color: Color, thickness: float) -> LineEncoding:
    """What :func:`amex.log.messages.line_update` puts around the points, as the SDK's bytes."""
    line = LinePrimitive(thickness=thickness, scale_invariant=True)
    return LineEncoding(
        SceneEntity(frame_id=WORLD_FRAME, id=entity).encode(),
        line.encode(),
        LinePrimitive(color=color).encode(),
    )


def line_update(encoding: LineEncoding, ns: int, points: bytes) -> bytes:
    """The SceneUpdate of :func:`amex.log.messages.line_update` with ``points`` encoded.

    Args:
        encoding: the line's constant parts.
        ns: the timestamp [ns].
        points: the points, :func:`encode_vectors` with tag ``LinePrimitive.points``.
    """
    line = encoding.head + points + encoding.tail
    entity = timestamp_field(ns) + encoding.entity + _field(_LINES, line)
    return _field(_ENTITIES, entity)


def line_points(xyz: np.ndarray) -> bytes:
    """The points of a line (rows of ``xyz``, (k, >= 3)) as ``LinePrimitive.points`` fields."""
    return encode_vectors(xyz, _POINT)


class SphereEncoding(NamedTuple):
    """The constant parts of a sphere: the pose's orientation, and the size and colour."""

    orientation: bytes
    rest: bytes


def sphere_encoding(diameter: float, color: Color) -> SphereEncoding:
    """What :func:`amex.log.messages.sphere` puts around the centre, as the SDK's bytes."""
    size = Vector3(x=diameter, y=diameter, z=diameter)
    return SphereEncoding(
        Pose(orientation=IDENTITY).encode(),
        SpherePrimitive(size=size, color=color).encode(),
    )


def spheres_entity(ns: int, entity: bytes, spheres: list[tuple[SphereEncoding, bytes]]) -> bytes:
    """A SceneUpdate entity of spheres, each (its constant parts, its centre's position field).

    Args:
        ns: the timestamp [ns].
        entity: the SceneEntity's frame_id and id (``SceneEntity(...).encode()``).
        spheres: per sphere, its encoding and its centre (:func:`encode_vectors` with tag
            ``Pose.position``, one row).
    """
    body = [timestamp_field(ns), entity]
    for sphere, position in spheres:
        pose = _field(_POSE, position + sphere.orientation)
        body.append(_field(_SPHERES, pose + sphere.rest))
    return _field(_ENTITIES, b"".join(body))


def positions(xyz: np.ndarray) -> list[bytes]:
    """The ``Pose.position`` field of each row of ``xyz`` (k, 3)."""
    encoded = encode_vectors(xyz, _POSITION)
    out, i = [], 0
    while i < len(encoded):
        end = i + 2 + encoded[i + 1]
        out.append(encoded[i:end])
        i = end
    return out
