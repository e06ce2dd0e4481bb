"""The per-step ``/tf`` and ``/joint_states`` messages, protobuf-encoded in one compiled call.

What foxglove-sdk's typed channels write, byte for byte, without building its message objects
(those cost ~30 us per outer step, most of a log's cost). The constant parts come from the SDK's
own encoder, once per log (:class:`StepEncoding`): per transform, its frame names, translation and,
for a constant transform, its rotation (``FrameTransform(...).encode()`` without the timestamp,
fields in number order); per joint, its name. The compiled :func:`encode_step` writes what changes:
the timestamp (``google.protobuf.Timestamp``: zero fields omitted, the field itself always
present), the revolute transforms' rotations ``P * Rz(q_j)`` (the same floating-point operations
as :meth:`amex.log.frames.LinkTransforms.compute`, whose module has the derivation; zero
components omitted, as proto3 writes no defaults, -0.0 included), and each joint's position,
velocity, acceleration and effort (optional fields: always written). Compiled without
``fastmath``, with libm's ``sin``/``cos`` as ``math`` uses: the bytes equal the SDK's
(tests/log/test_wire.py compares them over random and exact-zero configurations).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import foxglove
import numba
import numpy as np
from foxglove.messages import FrameTransform, JointState, Quaternion, Vector3

_TRANSFORM = 0x0A  # FrameTransforms.transforms (field 1, length-delimited)
_TIMESTAMP = 0x0A  # FrameTransform.timestamp and JointStates.timestamp (field 1)
_JOINT = 0x12  # JointStates.joints (field 2)
_ROTATION = 0x2A  # FrameTransform.rotation (field 5)


class StepEncoding(NamedTuple):
    """The constant parts of one log's ``/tf`` and ``/joint_states`` messages.

    Attributes:
        blocks: per transform, then per joint, the SDK's bytes of the constant fields, joined.
        ends: where each block ends in ``blocks`` (transforms first, then joints), shape (k + n,).
        joint_index: per transform, the joint position index of its rotation, -1 if constant.
        rotation: per transform, the placement's quaternion (x, y, z, w), shape (k, 4).
        size: an upper bound of the two messages' length [bytes] (the output buffer's).
    """

    blocks: np.ndarray
    ends: np.ndarray
    joint_index: np.ndarray
    rotation: np.ndarray
    size: int


def step_encoding(
    transforms: Sequence[tuple[str, str, tuple[float, ...], tuple[float, ...], int]],
    joint_names: Sequence[str],
) -> StepEncoding:
    """The constant parts of the messages of ``transforms`` and ``joint_names``.

    Args:
        transforms: in message order, (parent, child, translation, quaternion (x, y, z, w),
            joint position index or -1): a transform with an index turns as ``P * Rz(q[index])``
            with its quaternion the placement's rotation P; one with -1 is constant.
        joint_names: the joints' names, in the order of q.
    """
    blocks: list[bytes] = []
    rotation = np.zeros((len(transforms), 4))
    index = np.full(len(transforms), -1, dtype=np.int64)
    for i, (parent, child, (tx, ty, tz), (x, y, z, w), idx) in enumerate(transforms):
        constant = Quaternion(x=x, y=y, z=z, w=w) if idx < 0 else None
        message = FrameTransform(
            parent_frame_id=parent,
            child_frame_id=child,
            translation=Vector3(x=tx, y=ty, z=tz),
            rotation=constant,
        )
        blocks.append(message.encode())
        rotation[i] = x, y, z, w
        index[i] = idx
    blocks += [JointState(name=name).encode() for name in joint_names]
    joined = b"".join(blocks)
    ends = np.cumsum([len(b) for b in blocks], dtype=np.int64)
    # per message: a timestamp (<= 2 + 11 + 6 bytes); per transform or joint: a tag and length
    # (<= 6 bytes), a timestamp (transforms) and a rotation (<= 2 + 4 * 9) or 4 doubles (joints)
    size = len(joined) + 2 * 19 + len(transforms) * (6 + 19 + 38) + len(joint_names) * (6 + 36)
    return StepEncoding(
        np.frombuffer(joined, dtype=np.uint8).copy(), ends, index, rotation, int(size)
    )


def protobuf_channel(topic: str, message: Any, context: foxglove.Context) -> foxglove.Channel:
    """A channel for pre-encoded ``message`` bytes: the SDK's typed channel's schema and encoding.

    Args:
        topic: the topic.
        message: the Foxglove message class (e.g. ``foxglove.messages.FrameTransforms``).
        context: the log's context.
    """
    schema = message.get_schema()
    return foxglove.Channel(
        topic,
        schema=foxglove.Schema(name=schema.name, encoding=schema.encoding, data=schema.data),
        message_encoding="protobuf",
        context=context,
    )


@numba.njit(cache=True)
def varint_field(out: np.ndarray, i: int, value: int) -> int:
    """Write ``value`` as a protobuf varint into ``out`` at ``i``; the index after it."""
    while value >= 0x80:
        out[i] = (value & 0x7F) | 0x80
        value >>= 7
        i += 1
    out[i] = value
    return i + 1


@numba.njit(cache=True)
def varint_size(value: int) -> int:
    """The bytes of ``value`` >= 0 as a protobuf varint."""
    n = 1
    while value >= 0x80:
        value >>= 7
        n += 1
    return n


@numba.njit(cache=True)
def double_field(out: np.ndarray, i: int, tag: int, value: float, scratch: np.ndarray) -> int:
    """Field ``tag`` (wire type 1) holding ``value``: the tag byte and 8 little-endian bytes."""
    out[i] = tag
    scratch[0] = value
    raw = scratch.view(np.uint8)
    for b in range(8):
        out[i + 1 + b] = raw[b]
    return i + 9


@numba.njit(cache=True)
def timestamp_size(seconds: int, nanos: int) -> int:
    """The bytes of a timestamp's body (:func:`write_timestamp`'s, its non-zero fields)."""
    size = 0
    if seconds:
        size += 1 + varint_size(seconds)
    if nanos:
        size += 1 + varint_size(nanos)
    return size


@numba.njit(cache=True)
def write_timestamp(out: np.ndarray, i: int, seconds: int, nanos: int) -> int:
    """The timestamp field (number 1): present, with its non-zero fields."""
    out[i] = _TIMESTAMP
    i = varint_field(out, i + 1, timestamp_size(seconds, nanos))
    if seconds:
        out[i] = 0x08
        i = varint_field(out, i + 1, seconds)
    if nanos:
        out[i] = 0x10
        i = varint_field(out, i + 1, nanos)
    return i


@numba.njit(cache=True)
def encode_step(
    ns: int,
    q: np.ndarray,
    v: np.ndarray,
    qacc: np.ndarray,
    tau: np.ndarray,
    blocks: np.ndarray,
    ends: np.ndarray,
    joint_index: np.ndarray,
    rotation: np.ndarray,
    out: np.ndarray,
) -> tuple[int, int]:
    """The ``/tf`` message into ``out[:a]`` and the ``/joint_states`` message into ``out[a:b]``.

    Args:
        ns: the step's simulation time [ns] (both messages' timestamp).
        q: joint positions, shape (n,) [rad].
        v: joint velocities, shape (n,) [rad/s].
        qacc: joint accelerations, shape (n,) [rad/s^2].
        tau: joint torques, shape (n,) [N m].
        blocks: :attr:`StepEncoding.blocks`.
        ends: :attr:`StepEncoding.ends`.
        joint_index: :attr:`StepEncoding.joint_index`.
        rotation: :attr:`StepEncoding.rotation`.
        out: the buffer, at least ``StepEncoding.size`` bytes.

    Returns:
        (a, b): the end of the ``/tf`` message and of the ``/joint_states`` message in ``out``.
    """
    seconds, nanos = ns // 1_000_000_000, ns % 1_000_000_000
    scratch = np.empty(1)
    quat = np.empty(4)
    stamp = np.empty(24, dtype=np.uint8)
    stamp_size = write_timestamp(stamp, 0, seconds, nanos)
    k = len(joint_index)
    i = 0
    start = 0
    for t in range(k):
        end = ends[t]
        size = stamp_size + (end - start)
        idx = joint_index[t]
        rot_size = 0
        if idx >= 0:
            x1, y1, z1, w1 = rotation[t, 0], rotation[t, 1], rotation[t, 2], rotation[t, 3]
            half = 0.5 * q[idx]
            s, c = math.sin(half), math.cos(half)
            quat[0] = x1 * c + y1 * s
            quat[1] = y1 * c - x1 * s
            quat[2] = z1 * c + w1 * s
            quat[3] = w1 * c - z1 * s
            for j in range(4):
                if quat[j] != 0.0:
                    rot_size += 9
            size += 2 + rot_size
        out[i] = _TRANSFORM
        i = varint_field(out, i + 1, size)
        out[i : i + stamp_size] = stamp[:stamp_size]
        i += stamp_size
        out[i : i + end - start] = blocks[start:end]
        i += end - start
        if idx >= 0:
            out[i] = _ROTATION
            out[i + 1] = rot_size
            i += 2
            for j in range(4):
                if quat[j] != 0.0:
                    i = double_field(out, i, 0x09 + 8 * j, quat[j], scratch)
        start = end
    tf_end = i
    out[i : i + stamp_size] = stamp[:stamp_size]
    i += stamp_size
    for j in range(len(ends) - k):
        end = ends[k + j]
        out[i] = _JOINT
        i = varint_field(out, i + 1, (end - start) + 36)
        out[i : i + end - start] = blocks[start:end]
        i += end - start
        i = double_field(out, i, 0x11, q[j], scratch)
        i = double_field(out, i, 0x19, v[j], scratch)
        i = double_field(out, i, 0x21, qacc[j], scratch)
        i = double_field(out, i, 0x29, tau[j], scratch)
        start = end
    return tf_end, i


@numba.njit(cache=True)
def encode_steps(
    ns: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    qacc: np.ndarray,
    tau: np.ndarray,
    blocks: np.ndarray,
    ends: np.ndarray,
    joint_index: np.ndarray,
    rotation: np.ndarray,
    out: np.ndarray,
    bounds: np.ndarray,
) -> int:
    """:func:`encode_step` for each row of a batch, one message after the other in ``out``.

    Args:
        ns: the steps' times [ns], shape (rows,).
        q: the steps' joint positions, shape (rows, n) [rad].
        v: their velocities, shape (rows, n) [rad/s].
        qacc: their accelerations, shape (rows, n) [rad/s^2].
        tau: their torques, shape (rows, n) [N m].
        blocks: :attr:`StepEncoding.blocks`.
        ends: :attr:`StepEncoding.ends`.
        joint_index: :attr:`StepEncoding.joint_index`.
        rotation: :attr:`StepEncoding.rotation`.
        out: the buffer, at least ``rows * StepEncoding.size`` bytes.
        bounds: set to, per row, where its ``/tf`` message starts, where it ends (and the
            ``/joint_states`` message starts) and where that ends in ``out``, shape (rows, 3).

    Returns:
        The bytes written.
    """
    i = 0
    for r in range(len(ns)):
        a, b = encode_step(
            ns[r], q[r], v[r], qacc[r], tau[r], blocks, ends, joint_index, rotation, out[i:]
        )
        bounds[r, 0] = i
        bounds[r, 1] = i + a
        bounds[r, 2] = i + b
        i += b
    return i
