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

import struct
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
from amex.log.wire import (
    double_field,
    timestamp_size,
    varint_field,
    varint_size,
    write_timestamp,
)

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


def line_update(encoding: LineEncoding, ns: int, points: bytes | bytearray) -> bytes:
    """The SceneUpdate of :func:`amex.log.messages.line_update` with ``points`` encoded.

    Args:
        encoding: the line's constant parts.
        ns: the timestamp [ns].
        points: the points, :func:`encode_vectors` with tag ``LinePrimitive.points``.
    """
    line = encoding.head + points + encoding.tail
    entity = timestamp_field(ns) + encoding.entity + _field(_LINES, line)
    return _field(_ENTITIES, entity)


def line_updates(
    encoding: LineEncoding, stamps: list[int], points: np.ndarray, ends: list[int]
) -> list[bytes]:
    """:func:`line_update` of each line, ``points[ends[j - 1]:ends[j]]`` at ``stamps[j]`` [ns].

    One compiled call (:func:`encode_lines`) for a batch's lines (CR's, MPPI's drawn plans),
    the same bytes as each line alone.

    Args:
        encoding: the lines' constant parts.
        stamps: per line, its timestamp [ns].
        points: the lines' points one after the other, shape (k, >= 3) [m].
        ends: per line, where its points end in ``points`` (non-decreasing, the last k).
    """
    xyz = np.ascontiguousarray(np.asarray(points, dtype=float)[:, :3])
    n = len(ends)
    constant = len(encoding.head) + len(encoding.entity) + len(encoding.tail)
    out = np.empty(29 * len(xyz) + n * (constant + 40), dtype=np.uint8)
    bounds = np.empty(n + 1, dtype=np.int64)
    encode_lines(
        np.asarray(stamps, dtype=np.int64),
        xyz,
        np.asarray(ends, dtype=np.int64),
        np.frombuffer(encoding.entity, dtype=np.uint8),
        np.frombuffer(encoding.head, dtype=np.uint8),
        np.frombuffer(encoding.tail, dtype=np.uint8),
        out,
        bounds,
    )
    data = out[: bounds[n]].tobytes()
    edges = bounds.tolist()
    return [data[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]


@numba.njit(cache=True)
def _copy_bytes(out: np.ndarray, i: int, block: np.ndarray) -> int:
    for b in range(len(block)):
        out[i + b] = block[b]
    return i + len(block)


@numba.njit(cache=True)
def encode_lines(
    stamps: np.ndarray,
    xyz: np.ndarray,
    ends: np.ndarray,
    entity: np.ndarray,
    head: np.ndarray,
    tail: np.ndarray,
    out: np.ndarray,
    bounds: np.ndarray,
) -> None:
    """Each line's SceneUpdate (:func:`line_updates`), one after the other in ``out``.

    ``SceneUpdate.entities`` holding a ``SceneEntity``: its timestamp, ``entity`` (frame_id
    and id) and ``lines`` holding a ``LinePrimitive``: ``head``, the points (each a field 5
    holding a Point3 of its non-zero coordinates) and ``tail``; lengths as varints.

    Args:
        stamps: per line, its timestamp [ns], shape (n,).
        xyz: the points, shape (k, 3) [m].
        ends: per line, where its points end in ``xyz``, shape (n,).
        entity: :attr:`LineEncoding.entity`'s bytes.
        head: :attr:`LineEncoding.head`'s bytes.
        tail: :attr:`LineEncoding.tail`'s bytes.
        out: the buffer (large enough).
        bounds: set to where each line's message starts, and the end, shape (n + 1,).
    """
    i = 0
    start = 0
    for j in range(len(ends)):
        bounds[j] = i
        end = ends[j]
        size = 0  # the points' bytes
        for r in range(start, end):
            size += 2 + _position_size(xyz[r])
        line = len(head) + size + len(tail)
        seconds, nanos = stamps[j] // 1_000_000_000, stamps[j] % 1_000_000_000
        stamp = timestamp_size(seconds, nanos)
        body = 1 + varint_size(stamp) + stamp + len(entity) + 1 + varint_size(line) + line
        out[i] = 0x12  # SceneUpdate.entities
        i = varint_field(out, i + 1, body)
        i = write_timestamp(out, i, seconds, nanos)
        i = _copy_bytes(out, i, entity)
        out[i] = 0x5A  # SceneEntity.lines
        i = varint_field(out, i + 1, line)
        i = _copy_bytes(out, i, head)
        i += _write_vectors(xyz[start:end], _POINT, out[i:])
        i = _copy_bytes(out, i, tail)
        start = end
    bounds[len(ends)] = i


def line_points(xyz: np.ndarray) -> bytes:
    """The points of a line (rows of ``xyz``, (k, >= 3)) as ``LinePrimitive.points`` fields."""
    return encode_vectors(xyz, _POINT)


_POINT_FIELD = struct.Struct("<BBBdBdBd")


def point_field(x: float, y: float, z: float) -> bytes:
    """One point of a line, ``line_points([[x, y, z]])``: one ``struct`` pack if none is zero."""
    if x and y and z:  # (a NaN is written, as a zero is not: proto3 omits the defaults)
        return _POINT_FIELD.pack(_POINT, 27, 0x09, x, 0x11, y, 0x19, z)
    return line_points(np.array([[x, y, z]], dtype=float))


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


class SpheresEncoding(NamedTuple):
    """The constant parts of a SceneUpdate of sphere entities, for :func:`encode_spheres`.

    Attributes:
        entities: the SceneEntities' frame_id and id fields, one after the other.
        entity_ends: where each entity's bytes end in :attr:`entities`, shape (E,).
        spheres: per sphere, its orientation and then the rest (:class:`SphereEncoding`).
        sphere_ends: per sphere, where its orientation and its rest end in :attr:`spheres`,
            shape (S, 2).
        sphere_entity: per sphere, its entity (non-decreasing), shape (S,).
        sphere_center: per sphere, the row of its centre among a step's centres, shape (S,).
    """

    entities: np.ndarray
    entity_ends: np.ndarray
    spheres: np.ndarray
    sphere_ends: np.ndarray
    sphere_entity: np.ndarray
    sphere_center: np.ndarray


def spheres_encoding(
    entities: list[tuple[bytes, list[tuple[SphereEncoding, int]]]],
) -> SpheresEncoding:
    """The layout of entities, each (``SceneEntity(...).encode()``, its spheres).

    A sphere is (its :func:`sphere_encoding`, the row of its centre among a step's centres).
    """
    blob, ends = b"", []
    parts, part_ends, owners, centers = b"", [], [], []
    for e, (entity, spheres) in enumerate(entities):
        blob += entity
        ends.append(len(blob))
        for sphere, center in spheres:
            parts += sphere.orientation
            orientation_end = len(parts)
            parts += sphere.rest
            part_ends.append((orientation_end, len(parts)))
            owners.append(e)
            centers.append(center)
    return SpheresEncoding(
        np.frombuffer(blob, np.uint8).copy(),
        np.array(ends, dtype=np.int64),
        np.frombuffer(parts, np.uint8).copy(),
        np.array(part_ends, dtype=np.int64).reshape(-1, 2),
        np.array(owners, dtype=np.int64),
        np.array(centers, dtype=np.int64),
    )


@numba.njit(cache=True)
def _position_size(center: np.ndarray) -> int:
    """The bytes of a Vector3's fields (zero coordinates omitted)."""
    size = 0
    for c in range(3):
        if center[c] != 0.0:
            size += 9
    return size


@numba.njit(cache=True)
def _sphere_body(center: np.ndarray, orientation: int, rest: int) -> tuple[int, int]:
    """A SpherePrimitive's bytes, and its pose's, at ``center``."""
    pose = 2 + _position_size(center) + orientation
    return 1 + varint_size(pose) + pose + rest, pose


@numba.njit(cache=True)
def encode_spheres(
    ns: np.ndarray,
    centers: np.ndarray,
    rows: np.ndarray,
    entities: np.ndarray,
    entity_ends: np.ndarray,
    spheres: np.ndarray,
    sphere_ends: np.ndarray,
    sphere_entity: np.ndarray,
    sphere_center: np.ndarray,
    out: np.ndarray,
    bounds: np.ndarray,
) -> int:
    """The SceneUpdate of :class:`SpheresEncoding`'s entities at each of ``rows``, in ``out``.

    The bytes of :func:`amex.log.messages.sphere`'s spheres in ``SceneEntity``'s of the
    SDK, one entity after the other, each with the row's timestamp.

    Args:
        ns: per row, the timestamp [ns], shape (k,).
        centers: per row, the spheres' centres [m], shape (k, c, 3).
        rows: the rows to encode, shape (r,).
        entities: :attr:`SpheresEncoding.entities`.
        entity_ends: :attr:`SpheresEncoding.entity_ends`.
        spheres: :attr:`SpheresEncoding.spheres`.
        sphere_ends: :attr:`SpheresEncoding.sphere_ends`.
        sphere_entity: :attr:`SpheresEncoding.sphere_entity`.
        sphere_center: :attr:`SpheresEncoding.sphere_center`.
        out: the buffer (large enough).
        bounds: set to where each of ``rows``' messages starts and ends in ``out``, (r, 2).

    Returns:
        The bytes written.
    """
    scratch = np.empty(1)
    i = 0
    n_spheres = len(sphere_entity)
    for j in range(len(rows)):
        r = rows[j]
        seconds, nanos = ns[r] // 1_000_000_000, ns[r] % 1_000_000_000
        stamp = timestamp_size(seconds, nanos)
        bounds[j, 0] = i
        s = 0
        for e in range(len(entity_ends)):
            start = entity_ends[e - 1] if e else 0
            body = 1 + varint_size(stamp) + stamp + entity_ends[e] - start
            first = s
            while s < n_spheres and sphere_entity[s] == e:  # the entity's spheres' sizes
                mid = sphere_ends[s, 0]
                low = sphere_ends[s - 1, 1] if s else 0
                center = centers[r, sphere_center[s]]
                size, _ = _sphere_body(center, mid - low, sphere_ends[s, 1] - mid)
                body += 1 + varint_size(size) + size
                s += 1
            out[i] = 0x12  # SceneUpdate.entities
            i = varint_field(out, i + 1, body)
            i = write_timestamp(out, i, seconds, nanos)
            end = entity_ends[e]
            out[i : i + end - start] = entities[start:end]
            i += end - start
            for t in range(first, s):
                center = centers[r, sphere_center[t]]
                mid = sphere_ends[t, 0]
                low = sphere_ends[t - 1, 1] if t else 0
                size, pose = _sphere_body(center, mid - low, sphere_ends[t, 1] - mid)
                out[i] = 0x4A  # SceneEntity.spheres
                i = varint_field(out, i + 1, size)
                out[i] = 0x0A  # SpherePrimitive.pose
                i = varint_field(out, i + 1, pose)
                out[i] = _POSITION
                out[i + 1] = _position_size(center)
                i += 2
                for c in range(3):
                    if center[c] != 0.0:
                        i = double_field(out, i, 0x09 + 8 * c, center[c], scratch)
                high = sphere_ends[t, 1]
                out[i : i + high - low] = spheres[low:high]
                i += high - low
        bounds[j, 1] = i
    return i


@numba.njit(cache=True)
def due_rows(
    times: np.ndarray, keys: np.ndarray, last: np.ndarray, since: np.ndarray, out: np.ndarray
) -> int:
    """The rows where what the spheres' centres key moved by 1e-3 or more, or a second passed.

    ``moved`` is the sum of the absolute differences of the row's ``keys`` and the last
    drawn row's, left to right; a NaN counts as a move. The first row is due if ``since[0]``
    is NaN (nothing drawn yet).

    Args:
        times: per row, its time [s], shape (k,).
        keys: per row, the values that count as motion (goal, then the obstacles if they
            move), shape (k, K).
        last: the last drawn row's keys, updated here, shape (K,).
        since: ``[the last drawn row's time]`` (NaN: none yet), updated here, shape (1,).
        out: set to the due rows, in order, shape (k,).

    Returns:
        How many rows are due.
    """
    n = 0
    for r in range(len(times)):
        t = times[r]
        if not np.isnan(since[0]) and t < since[0] + 1.0:
            moved = 0.0
            for c in range(keys.shape[1]):
                moved += abs(keys[r, c] - last[c])
            if moved < 1e-3:
                continue
        last[:] = keys[r]
        since[0] = t
        out[n] = r
        n += 1
    return n
