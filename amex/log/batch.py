"""The outer steps a log keeps until it writes them: numbers in rows, encoded a batch at a time.

:class:`StepBatch` keeps what the log needs of each step (:meth:`StepBatch.add`): the simulator's
buffers (q_ddot, tau) are copied as their doubles' bytes and the command's parts into
preallocated rows (a task-space command, the usual one, by two slice copies); q, q_dot, y,
y_dot and the goal, which the episode loop makes anew at every outer step for the observation
and the logs (:mod:`amex.sim.episode`), are kept as they are, with the step's time and which
command parts it has, and put into their rows a batch at a time (:meth:`StepBatch.fill`: one
concatenation each per batch instead of a copy each per step, which ran cold between the inner
steps); the rest (obstacles, command of another shape, internals) is kept as the step gave it,
copied where the loop or the method may reuse a buffer.
:meth:`StepBatch.encode` then writes every row's ``/tf`` and ``/joint_states``
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
import struct
from typing import TYPE_CHECKING, Any, NamedTuple

import numba
import numpy as np

from amex.core.lazy import Lazy
from amex.log.flat_proto import varint
from amex.log.wire import StepEncoding, double_field, encode_steps, varint_field

if TYPE_CHECKING:
    from amex.sim.loop import StepRecord


class Kept(NamedTuple):
    """What a step keeps besides its rows (module notes)."""

    obstacles: np.ndarray  # the observation's (a new array each step)
    command: bytes | None  # the /command message of a command of another shape, else None
    method: dict[str, Any]  # what /method needs: its snapshot, or a fresh method's internals
    plan: Any  # where the scene draws it, internals()["plan"]: copied, or its Lazy; else None


class Encoded(NamedTuple):
    """A batch's messages: one buffer and, per row, where each message ends in it."""

    data: bytes
    joints: np.ndarray | None  # (rows, 3): /tf from [0] to [1], /joint_states to [2]; or None
    numbers: np.ndarray  # (rows, 4): /tcp from [0] to [1], /goal to [2], /command to [3]


class StepBatch:
    """Up to ``capacity`` outer steps of ``n`` joints and an ``m``-dimensional task space.

    Args:
        capacity: rows (the logger's batch).
        n: joint coordinates (q, q_dot, q_ddot, tau each).
        m: task-space coordinates (y, y_dot each; the TCP's position and z-axis for m = 6).
        encoding: the constant parts of ``/tf`` and ``/joint_states``, None if those are built
            as the SDK's objects (then :attr:`Encoded.joints` is None).
        fresh: the method's :attr:`~amex.methods.base.Method.fresh_steps`: a task-space
            command's arrays are kept as they are, put into the rows by :meth:`fill`.

    Attributes:
        count: the rows filled.
        t, ns, q, v, qacc, tau, y, yd, goal: the rows (only the first :attr:`count` are valid;
            all but the command's once :meth:`fill` ran).
        kept: per row, its :class:`Kept`.
    """

    def __init__(
        self, capacity: int, n: int, m: int, encoding: StepEncoding | None, *, fresh: bool = False
    ) -> None:
        self.count = 0
        self._fresh_commands = fresh
        self._task: list[tuple[int, Any, Any]] = []  # (row, y*, y_dot*) kept as given
        self.t = np.zeros(capacity)
        self.ns = np.zeros(capacity, dtype=np.int64)
        self.q, self.v, self.qacc, self.tau = (np.zeros((capacity, n)) for _ in range(4))
        self.y, self.yd = np.zeros((capacity, m)), np.zeros((capacity, m))
        self.goal = np.zeros((capacity, 3))
        self._sizes = np.array([m, m, n, n], dtype=np.int64)  # y*, y_dot*, q*, q_dot*
        self._offsets = np.concatenate([[0], np.cumsum(self._sizes)]).tolist()
        self.command = np.zeros((capacity, 2 * (m + n)))
        self.parts = np.zeros(capacity, dtype=np.int64)  # bit j: the command has part j
        self.kept: list[Kept] = []
        # per row: t, q, q_dot, y, y_dot, goal, parts, and the bytes of q_ddot and tau
        self._fresh: list[tuple[Any, ...]] = []
        self._m = m
        ends = self._offsets
        self._slices = [slice(a, b) for a, b in zip(ends[:-1], ends[1:], strict=True)]
        self._packers: dict[tuple[int, ...], tuple[struct.Struct, list[bytes]]] = {}
        self._encoding = encoding
        self._joint_size = encoding.size if encoding is not None else 0
        row = self._joint_size + _NUMBERS_SIZE + 8 * m + 9 + 4 * 12 + 8 * 2 * (m + n)
        self._out = np.empty(capacity * row, np.uint8)
        self._bounds = np.zeros((capacity, 3), dtype=np.int64)
        self._number_bounds = np.zeros((capacity, 4), dtype=np.int64)

    def __len__(self) -> int:
        return self.count

    def add(self, step: StepRecord, method: dict[str, Any], plan: Any) -> int:
        """Keep ``step`` as the next row (the batch must not be full; module notes); the count.

        Args:
            step: the outer step.
            method: what its ``/method`` message needs
                (:meth:`~amex.log.method_topic.MethodTopic.snapshot`, or the internals
                themselves of a method of :attr:`~amex.methods.base.Method.fresh_steps`).
            plan: its plan to draw (copied here; a :class:`~amex.core.lazy.Lazy` is kept as it
                is, to be computed when the batch is written), or None.
        """
        i = self.count
        t, state, obs, command, _, tau, qacc = step
        # the simulator's buffers: copied here, as their doubles' bytes (a third of a row copy)
        qacc_bytes = qacc.tobytes() if qacc.dtype is _F8 else np.asarray(qacc, float).tobytes()
        tau_bytes = tau.tobytes() if tau.dtype is _F8 else np.asarray(tau, float).tobytes()
        packed = None
        m = self._m
        if len(command) == 4 and command[2] is None and command[3] is None:  # y*, y_dot*
            y, yd = command[0], command[1]
            if y is not None and yd is not None and len(y) == m and len(yd) == m:
                if self._fresh_commands:
                    self._task.append((i, y, yd))
                else:
                    row, slices = self.command[i], self._slices
                    row[slices[0]] = y
                    row[slices[1]] = yd
                parts = _TASK_PARTS
            else:
                parts, packed = self._command_row(i, t, command)
        else:
            parts, packed = self._command_row(i, t, command)
        if plan is not None and not isinstance(plan, Lazy):  # a lazy one is a snapshot
            plan = np.array(plan, dtype=float)
        self.kept.append(tuple.__new__(Kept, (obs.obstacles, packed, method, plan)))
        self._fresh.append(
            (t, state.q, state.v, obs.y, obs.yd, obs.goal, parts, qacc_bytes, tau_bytes)
        )
        self.count = i = i + 1
        return i

    def _command_row(
        self, i: int, t: float, command: tuple[np.ndarray | None, ...]
    ) -> tuple[int, bytes | None]:
        """Row ``i``'s command parts and their bits; or the packed message, another shape."""
        if len(command) <= 4:
            row, slices, flags = self.command[i], self._slices, 0
            for j, part in enumerate(command):
                if part is not None:
                    if len(part) != slices[j].stop - slices[j].start:
                        return _PACKED_PARTS, self._packed_command(t, command)
                    row[slices[j]] = part
                    flags |= 1 << j
            return flags, None
        return _PACKED_PARTS, self._packed_command(t, command)

    def _packed_command(self, t: float, command: tuple[np.ndarray | None, ...]) -> bytes:
        """``/command`` of a command of another shape than (m, m[, n, n]), packed here."""
        values = [None if part is None else np.asarray(part, float).tolist() for part in command]
        key = tuple(-1 if v is None else len(v) for v in values)
        if key not in self._packers:
            self._packers[key] = _command_packer(key)
        packer, prefixes = self._packers[key]
        args: list[Any] = [b"\x09", t]
        for prefix, part in zip(prefixes, values, strict=True):
            if part is not None:
                args.append(prefix)
                args += part
        return packer.pack(*args)

    def clear(self) -> None:
        """Empty the batch: the next step goes into the first row (:attr:`kept` is a new list)."""
        self.count = 0
        self.kept = []
        self._fresh = []
        self._task = []

    def fill(self) -> int:
        """Fill the rows from the arrays :meth:`add` kept (before :meth:`clear`); their count."""
        k = self.count
        if k and self._fresh:
            t, q, v, y, yd, goal, parts, qacc, tau = zip(*self._fresh, strict=True)
            self.t[:k] = t
            self.parts[:k] = parts
            self.qacc[:k] = np.frombuffer(b"".join(qacc)).reshape(self.qacc[:k].shape)
            self.tau[:k] = np.frombuffer(b"".join(tau)).reshape(self.tau[:k].shape)
            if self._task:  # a fresh method's task-space commands, as they were given
                rows, ys, yds = zip(*self._task, strict=True)
                m = self._m
                # every row's (the usual batch): a slice, a third of an index's time
                index = slice(0, k) if len(rows) == k else list(rows)
                self.command[index, :m] = np.concatenate(ys).reshape(-1, m)
                self.command[index, m : 2 * m] = np.concatenate(yds).reshape(-1, m)
            # into the first k rows, contiguous: one concatenation each (np.stack makes a view
            # of every array first, ~3 times the time)
            np.concatenate(q, out=self.q[:k].reshape(-1))
            np.concatenate(v, out=self.v[:k].reshape(-1))
            np.concatenate(y, out=self.y[:k].reshape(-1))
            np.concatenate(yd, out=self.yd[:k].reshape(-1))
            self.goal[:k] = np.concatenate(goal).reshape(k, -1)[:, :3]
            self.ns[:k] = np.rint(self.t[:k] * 1e9)  # as round(t * 1e9): ties to even
        return k

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
            self.t[:k],
            self.y[:k],
            self.yd[:k],
            self.goal[:k],
            self.command[:k],
            self.parts[:k],
            self._sizes,
            out[start:],
            numbers,
        )
        numbers += start
        return Encoded(out[: start + end].tobytes(), joints, numbers)


_F8 = np.dtype(np.float64)
_TASK_PARTS = 0b0011  # a row's command parts, bit j for part j: y*, y_dot*
_PACKED_PARTS = -1  # not in the rows: written from its kept message

# /tcp: t, 3 + 3 + 3 doubles, distance: 9 + 3 * (2 + 24) + 9; /goal: 9 + 26 + 9 bytes
_NUMBERS_SIZE = 96 + 44


@numba.njit(cache=True)
def _packed(out: np.ndarray, i: int, tag: int, values: np.ndarray, scratch: np.ndarray) -> int:
    """Field ``tag`` (< 16, wire type 2) holding ``values`` as packed doubles."""
    out[i] = tag
    i = varint_field(out, i + 1, 8 * len(values))
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
    command: np.ndarray,
    parts: np.ndarray,
    sizes: np.ndarray,
    out: np.ndarray,
    bounds: np.ndarray,
) -> int:
    """Each row's ``/tcp``, ``/goal`` and ``/command`` message, one after the other in ``out``.

    Args:
        t: the steps' times [s], shape (rows,).
        y: the TCP's task state (position, z-axis), shape (rows, m) [m, -].
        yd: its rate, shape (rows, m) [m/s, 1/s].
        goal: the goal positions, shape (rows, 3) [m].
        command: y*, y_dot*, q*, q_dot* one after the other, shape (rows, 2 m + 2 n).
        parts: per row, bit j set if the command has part j (y*, y_dot*, q*, q_dot*); -1:
            no ``/command`` here (the row's command has another shape), shape (rows,).
        sizes: the parts' sizes (m, m, n, n).
        out: the buffer (:class:`StepBatch` sizes it).
        bounds: set to, per row, where its ``/tcp``, ``/goal`` and ``/command`` messages start
            and where the last ends in ``out``, shape (rows, 4).

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
        i = double_field(out, i, 0x09, t[r], scratch)
        i = _packed(out, i, 0x12, y[r, :3], scratch)
        i = _packed(out, i, 0x1A, y[r, 3:axis_end], scratch)
        i = _packed(out, i, 0x22, yd[r, :3], scratch)
        i = double_field(out, i, 0x29, distance, scratch)
        bounds[r, 1] = i
        i = double_field(out, i, 0x09, t[r], scratch)
        i = _packed(out, i, 0x12, goal[r], scratch)
        i = double_field(out, i, 0x19, distance, scratch)
        bounds[r, 2] = i
        if parts[r] >= 0:
            i = double_field(out, i, 0x09, t[r], scratch)
            start = 0
            for j in range(4):
                end = start + sizes[j]
                if parts[r] >> j & 1:
                    i = _packed(out, i, 0x12 + 8 * j, command[r, start:end], scratch)
                start = end
        bounds[r, 3] = i
    return i


def _command_packer(sizes: tuple[int, ...]) -> tuple[struct.Struct, list[bytes]]:
    """The packer of ``/command`` for parts of ``sizes`` (-1: absent) and each part's key."""
    prefixes = [
        varint(j << 3 | 2) + varint(8 * n) if n >= 0 else b"" for j, n in enumerate(sizes, 2)
    ]
    layout = "".join(f"{len(p)}s{n}d" for p, n in zip(prefixes, sizes, strict=True) if n >= 0)
    return struct.Struct("<1sd" + layout), prefixes
