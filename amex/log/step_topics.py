"""A log's per-step topics: /tf, /joint_states, /tcp, /goal, /command and /method.

What :meth:`amex.log.writer.EpisodeLogger.record` writes at every outer step besides the scene
(the module docstring of :mod:`amex.log.writer` lists the contents), at the cost that matters: a
log is written at 100 Hz beside an inner loop of ~0.2-0.3 ms per outer step. ``/tf`` and
``/joint_states`` are encoded in one compiled call (:mod:`amex.log.wire`, the SDK's bytes
without its objects; the SDK's objects when some transform takes the generic path); ``/tcp``,
``/goal`` and ``/command`` are formatted by one %-template (``"%.9g"`` numbers, non-finite ones
as null on a slow path); ``/method`` by :class:`amex.log.method_topic.MethodTopic`.
"""

from __future__ import annotations

import math
import struct
from typing import TYPE_CHECKING, Any, NamedTuple

import foxglove
import numpy as np
from foxglove.messages import JointState, JointStates, Timestamp

from amex.log import flat_proto as P
from amex.log.constants import LogConstants
from amex.log.method_topic import MethodTopic
from amex.log.wire import encode_step

if TYPE_CHECKING:
    from amex.sim.loop import StepRecord


class Captured(NamedTuple):
    """One outer step as :func:`capture` keeps it until the logger writes it (module notes)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    qacc: np.ndarray
    tau: np.ndarray
    y: np.ndarray
    yd: np.ndarray
    goal: np.ndarray
    obstacles: np.ndarray
    command: tuple[np.ndarray | None, ...]
    internals: dict[str, Any]


def capture(step: StepRecord) -> Captured:
    """What the log needs of ``step``, copied where the loop or the method may reuse a buffer.

    The episode loop copies q and q_dot at outer steps and builds a new observation (its task
    state and goal) each time; the accelerations and torques are the simulator's buffers, and
    a method may reuse its command's or internals' arrays: those are copied.
    """
    state, obs = step.state, step.observation
    command = tuple(None if p is None else p.copy() for p in step.command)
    internals = {
        k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in step.internals.items()
    }
    return Captured(
        step.t,
        state.q,
        state.v,
        np.array(step.qacc, dtype=float),
        np.array(step.tau, dtype=float),
        obs.y,
        obs.yd,
        obs.goal,
        obs.obstacles,
        command,
        internals,
    )


# /tcp and /goal: every field, in field-number order (amex.log.flat_proto's TCP and GOAL)
_TCP = struct.Struct("<1sd2s3d2s3d2s3d1sd")
_GOAL = struct.Struct("<1sd2s3d1sd")
# /command: the keys of y*, y_dot*, q*, q_dot* (fields 2-5, packed doubles); t is field 1
_COMMAND_FIELDS = (b"\x12", b"\x1a", b"\x22", b"\x2a")


class StepTopics:
    """The per-step topics of one log (module notes).

    Args:
        context: the log's context (``/method`` is created in it at the first step).
        constants: the run's :class:`~amex.log.constants.LogConstants`.
        channels: the channels of ``/tf``, ``/joint_states``, ``/tcp``, ``/goal`` and
            ``/command`` (``foxglove.Channel``), created by the logger in its topic order.

    Attributes:
        method_channel: ``/method``'s channel once the first step made it, else None.
    """

    def __init__(
        self, context: foxglove.Context, constants: LogConstants, channels: dict[str, Any]
    ) -> None:
        self._context = context
        self._constants = constants
        self._channels = {topic: channel.base for topic, channel in channels.items()}
        self._tf = self._channels["/tf"]
        self._joint_states = self._channels["/joint_states"]
        encoding = constants.encoding
        self._buffer = np.empty(encoding.size if encoding else 0, dtype=np.uint8)
        self._command_encodings: dict[tuple[int, ...], Any] = {}  # by the parts' sizes
        self._method = MethodTopic()  # /method's schema, at the first step
        self.method_channel: foxglove.Channel | None = None

    def record(self, step: Captured, ns: int) -> tuple[list[float], Any]:
        """Log one outer step at ``ns`` [ns]; the TCP position [m] and ``internals()["plan"]``."""
        t = step.t
        self._log_joints(ns, step.q, step.v, step.qacc, step.tau)
        y, yd = step.y.tolist(), step.yd.tolist()  # (TCP position, z-axis) and their rates
        gx, gy, gz = step.goal[:3].tolist()
        tcp = y[:3]
        distance = math.dist(tcp, (gx, gy, gz))
        self._log_numbers_of_step(t, y, yd, (gx, gy, gz), distance, step.command, ns)
        internals = step.internals
        plan = None
        if "plan" in internals:
            plan = internals.pop("plan")  # the captured copy: ours to change
        self._log_method(t, internals, ns)
        return tcp, plan

    def _log_joints(
        self, ns: int, q: np.ndarray, v: np.ndarray, qacc: np.ndarray, tau: np.ndarray
    ) -> None:
        """``/tf`` and ``/joint_states``: encoded in one compiled call (:mod:`amex.log.wire`)."""
        encoding = self._constants.encoding
        if encoding is not None:
            out = self._buffer
            a, b = encode_step(
                ns,
                q,
                v,
                qacc,
                tau,
                encoding.blocks,
                encoding.ends,
                encoding.joint_index,
                encoding.rotation,
                out,
            )
            self._tf.log(out[:a].tobytes(), ns)
            self._joint_states.log(out[a:b].tobytes(), ns)
            return
        stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)  # sim_stamp(t)
        self._tf.log(self._constants.links.message(q, stamp).encode(), ns)
        qs, vs = q.tolist(), v.tolist()
        qdd, taus = np.asarray(qacc).tolist(), np.asarray(tau).tolist()
        joints = [
            JointState(name=n, position=a, velocity=b, acceleration=c, effort=d)
            for n, a, b, c, d in zip(self._constants.joint_names, qs, vs, qdd, taus, strict=False)
        ]
        self._joint_states.log(JointStates(timestamp=stamp, joints=joints).encode(), ns)

    def _log_numbers_of_step(
        self,
        t: float,
        y: list[float],
        yd: list[float],
        goal: tuple[float, float, float],
        distance: float,
        command: Any,
        ns: int,
    ) -> None:
        """``/tcp``, ``/goal`` and ``/command``: every field (:mod:`amex.log.flat_proto`)."""
        channels = self._channels
        channels["/tcp"].log(
            _TCP.pack(b"\x09", t, b"\x12\x18", *y[:3], b"\x1a\x18", *y[3:6], b"\x22\x18", *yd[:3],
                      b"\x29", distance),
            ns,
        )  # fmt: skip
        channels["/goal"].log(_GOAL.pack(b"\x09", t, b"\x12\x18", *goal, b"\x19", distance), ns)
        parts = [None if part is None else part.tolist() for part in command]
        key = tuple(-1 if part is None else len(part) for part in parts)
        encoding = self._command_encodings.get(key)
        if encoding is None:
            encoding = self._command_encodings[key] = _command_encoding(key)
        packer, prefixes = encoding
        args: list[Any] = [b"\x09", t]
        for prefix, part in zip(prefixes, parts, strict=False):
            if part is not None:
                args.append(prefix)
                args += part
        channels["/command"].log(packer.pack(*args), ns)

    def _log_method(self, t: float, internals: Any, ns: int) -> None:
        """``/method``: the numbers, flags, texts and small number arrays of ``internals()``.

        The channel and its schema are made at the first step from the values then
        (:class:`amex.log.method_topic.MethodTopic`).
        """
        method = self._method
        if method.kinds is None:
            self.method_channel = method.schema(t, internals).channel("/method", self._context)
            self._channels["/method"] = self.method_channel.base
        self._channels["/method"].log(method.encode(t, internals), ns)


def _command_encoding(sizes: tuple[int, ...]) -> tuple[struct.Struct, list[bytes]]:
    """The packer of ``/command`` for parts of ``sizes`` (-1: absent) and each part's key."""
    keys = zip(_COMMAND_FIELDS, sizes, strict=False)  # a command has 2 or 4 parts
    prefixes = [key + P.varint(8 * n) if n >= 0 else b"" for key, n in keys]
    layout = "".join(f"{len(p)}s{n}d" for p, n in zip(prefixes, sizes, strict=False) if n >= 0)
    return struct.Struct("<1sd" + layout), prefixes
