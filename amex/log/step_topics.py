"""A log's per-step topics: /tf, /joint_states, /tcp, /goal, /command and /method.

What :class:`amex.log.writer.EpisodeLogger` writes at every outer step besides the scene (the
module docstring of :mod:`amex.log.writer` lists the contents), at the cost that matters: a log
is written at 100 Hz beside an inner loop of ~0.2-0.3 ms per outer step. The steps come a batch
at a time (:class:`amex.log.batch.StepBatch`): ``/tf``, ``/joint_states``, ``/tcp`` and ``/goal``
are encoded for the whole batch in two compiled calls (:mod:`amex.log.wire`, the SDK's bytes
without its objects; the SDK's objects when some transform takes the generic path), so a step
costs their SDK writes; ``/command`` is packed per step by a ``struct`` made once per shape of
command, and ``/method`` by :class:`amex.log.method_topic.MethodTopic`. ``/tcp``, ``/goal``,
``/command`` and ``/method`` are amex's protobuf messages (:mod:`amex.log.flat_proto`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from typing import Any

import foxglove
import numpy as np
from foxglove.messages import JointState, JointStates, Timestamp

from amex.log import flat_proto as P
from amex.log.batch import Kept, StepBatch
from amex.log.constants import LogConstants
from amex.log.method_topic import MethodTopic

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
        self._command_encodings: dict[tuple[int, ...], Any] = {}  # by the parts' sizes
        self._method = MethodTopic()  # /method's schema, at the first step
        self.method_channel: foxglove.Channel | None = None

    def write(
        self, batch: StepBatch, k: int, kept: list[Kept]
    ) -> Iterator[tuple[float, list[float], Any]]:
        """Log the first ``k`` rows of ``batch`` (and their ``kept``) in order.

        After each step, yields its time [s], TCP position [m] and ``internals()["plan"]``
        (None if it has none), for the scene.
        """
        encoded = batch.encode(k)
        data = encoded.data
        times, stamps = batch.t[:k].tolist(), batch.ns[:k].tolist()
        tcps = batch.y[:k, :3].tolist()
        numbers = encoded.numbers.tolist()
        joints = encoded.joints.tolist() if encoded.joints is not None else None
        channels = self._channels
        tf, joint_states = channels["/tf"], channels["/joint_states"]
        tcp_channel, goal_channel = channels["/tcp"], channels["/goal"]
        for i in range(k):
            t, ns, step = times[i], stamps[i], kept[i]
            if joints is not None:
                a, b, c = joints[i]
                tf.log(data[a:b], ns)
                joint_states.log(data[b:c], ns)
            else:
                self._log_joints_generic(ns, batch.q[i], batch.v[i], batch.qacc[i], batch.tau[i])
            a, b, c = numbers[i]
            tcp_channel.log(data[a:b], ns)
            goal_channel.log(data[b:c], ns)
            self._log_command(t, step.command, ns)
            internals = step.internals
            plan = internals.pop("plan", None)  # the kept copy: ours to change
            self._log_method(t, internals, ns)
            yield t, tcps[i], plan

    def _log_joints_generic(
        self, ns: int, q: np.ndarray, v: np.ndarray, qacc: np.ndarray, tau: np.ndarray
    ) -> None:
        """``/tf`` and ``/joint_states`` as the SDK's objects (a transform of no compiled kind)."""
        stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)  # sim_stamp(t)
        self._channels["/tf"].log(self._constants.links.message(q, stamp).encode(), ns)
        qs, vs, qdd, taus = q.tolist(), v.tolist(), qacc.tolist(), tau.tolist()
        joints = [
            JointState(name=n, position=a, velocity=b, acceleration=c, effort=d)
            for n, a, b, c, d in zip(self._constants.joint_names, qs, vs, qdd, taus, strict=False)
        ]
        self._channels["/joint_states"].log(
            JointStates(timestamp=stamp, joints=joints).encode(), ns
        )

    def _log_command(self, t: float, command: Any, ns: int) -> None:
        """``/command``: y*, y_dot* (and q*, q_dot*), whichever parts the command has."""
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
        self._channels["/command"].log(packer.pack(*args), ns)

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
