"""The outer steps a log keeps until it writes them: numbers in rows, encoded a batch at a time.

:class:`StepBatch` copies what the log needs of each step (:meth:`StepBatch.add`) into
preallocated rows (time, q, q_dot, q_ddot, tau, y, y_dot, goal) and keeps the rest (obstacles,
command, internals) as the step gave them, copied where the loop or the method may reuse a
buffer. :meth:`StepBatch.encode` then writes every row's ``/tf`` and ``/joint_states``
(:func:`amex.log.wire.encode_steps`) and ``/tcp`` and ``/goal`` (:func:`encode_numbers`) in two
compiled calls: the per-step Python is left with the SDK's writes (issue #29: one compiled call
per message and step cost ~2 us of dispatch each).

``/tcp`` and ``/goal`` are messages of :data:`amex.log.flat_proto.TCP` and ``GOAL``, every field
written in field-number order: ``t``, the TCP position ``y[:3]``, its z-axis ``y[3:6]``, its
velocity ``y_dot[:3]`` and ``distance_to_goal``; ``t``, the goal position ``goal[:3]`` and
``distance``, both distances ``sqrt(dx^2 + dy^2 + dz^2)`` of the same doubles.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numba
import numpy as np

from amex.log.wire import StepEncoding, _double, encode_steps

if TYPE_CHECKING:
    from amex.sim.loop import StepRecord


class Kept(NamedTuple):
    """What a step keeps besides its rows: obstacles, command parts and internals (copies)."""

    obstacles: np.ndarray
    command: tuple[np.ndarray | None, ...]
    internals: dict[str, Any]


class Encoded(NamedTuple):
    """A batch's messages: one buffer and, per row, where each message ends in it."""

    data: bytes
    joints: np.ndarray | None  # (rows, 3): /tf from [0] to [1], /joint_states to [2]; or None
    numbers: np.ndarray  # (rows, 3): /tcp from [0] to [1], /goal to [2]


class StepBatch:
    """Up to ``capacity`` outer steps of ``n`` joints and an ``m``-dimensional task space.

    Args:
        capacity: rows (the logger's batch).
        n: joint coordinates (q, q_dot, q_ddot, tau each).
        m: task-space coordinates (y, y_dot each; the TCP's position and z-axis for m = 6).
        encoding: the constant parts of ``/tf`` and ``/joint_states``, None if those are built
            as the SDK's objects (then :attr:`Encoded.joints` is None).

    Attributes:
        count: the rows filled.
        t, ns, q, v, qacc, tau, y, yd, goal: the rows (only the first :attr:`count` are valid).
        kept: per row, its :class:`Kept`.
    """

    def __init__(self, capacity: int, n: int, m: int, encoding: StepEncoding | None) -> None:
        self.count = 0
        self.t = np.zeros(capacity)
        self.ns = np.zeros(capacity, dtype=np.int64)
        self.q, self.v, self.qacc, self.tau = (np.zeros((capacity, n)) for _ in range(4))
        self.y, self.yd = np.zeros((capacity, m)), np.zeros((capacity, m))
        self.goal = np.zeros((capacity, 3))
        self.kept: list[Kept] = []
        self._encoding = encoding
        self._joint_size = encoding.size if encoding is not None else 0
        self._out = np.empty(capacity * (self._joint_size + _NUMBERS_SIZE + 8 * m), np.uint8)
        self._bounds = np.zeros((capacity, 3), dtype=np.int64)
        self._number_bounds = np.zeros((capacity, 3), dtype=np.int64)

    def __len__(self) -> int:
        return self.count

    def add(self, step: StepRecord) -> None:
        """Copy ``step`` into the next row (the batch must not be full)."""
        i = self.count
        state, obs = step.state, step.observation
        t = step.t
        self.t[i] = t
        self.ns[i] = round(t * 1e9)
        self.q[i] = state.q
        self.v[i] = state.v
        self.qacc[i] = step.qacc  # the simulator's buffers: copied here
        self.tau[i] = step.tau
        self.y[i] = obs.y
        self.yd[i] = obs.yd
        self.goal[i] = obs.goal[:3]
        command = tuple(None if p is None else p.copy() for p in step.command)
        internals = {
            k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in step.internals.items()
        }
        self.kept.append(Kept(obs.obstacles, command, internals))
        self.count = i + 1

    def clear(self) -> None:
        """Empty the batch: the next step goes into the first row (:attr:`kept` is a new list)."""
        self.count = 0
        self.kept = []

    def encode(self, k: int) -> Encoded:
        """The first ``k`` rows' ``/tf``, ``/joint_states``, ``/tcp`` and ``/goal`` messages."""
        out = self._out
        start = 0
        joints = None
        encoding = self._encoding
        if encoding is not None:
            joints = self._bounds[:k]
            start = encode_steps(
                self.ns[:k],
                self.q[:k],
                self.v[:k],
                self.qacc[:k],
                self.tau[:k],
                encoding.blocks,
                encoding.ends,
                encoding.joint_index,
                encoding.rotation,
                out,
                joints,
            )
        numbers = self._number_bounds[:k]
        end = encode_numbers(
            self.t[:k], self.y[:k], self.yd[:k], self.goal[:k], out[start:], numbers
        )
        numbers += start
        return Encoded(out[: start + end].tobytes(), joints, numbers)


# /tcp: t, 3 + 3 + 3 doubles, distance: 9 + 3 * (2 + 24) + 9; /goal: 9 + 26 + 9 bytes
_NUMBERS_SIZE = 96 + 44


@numba.njit(cache=True)
def _packed(out: np.ndarray, i: int, tag: int, values: np.ndarray, scratch: np.ndarray) -> int:
    """Field ``tag`` (wire type 2) holding ``values`` as packed doubles (< 16 of them)."""
    out[i] = tag
    out[i + 1] = 8 * len(values)
    i += 2
    raw = scratch.view(np.uint8)
    for value in values:
        scratch[0] = value
        for b in range(8):
            out[i + b] = raw[b]
        i += 8
    return i


@numba.njit(cache=True)
def encode_numbers(
    t: np.ndarray,
    y: np.ndarray,
    yd: np.ndarray,
    goal: np.ndarray,
    out: np.ndarray,
    bounds: np.ndarray,
) -> int:
    """Each row's ``/tcp`` and ``/goal`` message, one after the other in ``out`` (module notes).

    Args:
        t: the steps' times [s], shape (rows,).
        y: the TCP's task state (position, z-axis), shape (rows, m) [m, -].
        yd: its rate, shape (rows, m) [m/s, 1/s].
        goal: the goal positions, shape (rows, 3) [m].
        out: the buffer, at least 140 + 8 m bytes per row.
        bounds: set to, per row, where its ``/tcp`` message starts, where it ends (and the
            ``/goal`` message starts) and where that ends in ``out``, shape (rows, 3).

    Returns:
        The bytes written.
    """
    scratch = np.empty(1)
    axis_end = min(y.shape[1], 6)
    i = 0
    for r in range(len(t)):
        dx, dy, dz = y[r, 0] - goal[r, 0], y[r, 1] - goal[r, 1], y[r, 2] - goal[r, 2]
        distance = math.sqrt(dx * dx + dy * dy + dz * dz)
        bounds[r, 0] = i
        i = _double(out, i, 0x09, t[r], scratch)
        i = _packed(out, i, 0x12, y[r, :3], scratch)
        i = _packed(out, i, 0x1A, y[r, 3:axis_end], scratch)
        i = _packed(out, i, 0x22, yd[r, :3], scratch)
        i = _double(out, i, 0x29, distance, scratch)
        bounds[r, 1] = i
        i = _double(out, i, 0x09, t[r], scratch)
        i = _packed(out, i, 0x12, goal[r], scratch)
        i = _double(out, i, 0x19, distance, scratch)
        bounds[r, 2] = i
    return i
