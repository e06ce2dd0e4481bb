"""A log's per-step topics: /tf, /joint_states, /tcp, /goal, /command and /method.

What :class:`amex.log.writer.EpisodeLogger` writes at every outer step besides the scene (the
module docstring of :mod:`amex.log.writer` lists the contents), at the cost that matters: a log
is written at 100 Hz beside an inner loop of ~0.2-0.3 ms per outer step. The steps come a batch
at a time (:class:`amex.log.batch.StepBatch`): ``/tf``, ``/joint_states``, ``/tcp``, ``/goal``
and ``/command`` are encoded for the whole batch in two compiled calls (:mod:`amex.log.wire`,
the SDK's bytes without its objects; the SDK's objects when some transform takes the generic
path), so a step costs their SDK writes; ``/method``'s values are taken when the step is kept
(:meth:`StepTopics.method_values`) and encoded with the batch. ``/tcp``, ``/goal``,
``/command`` and ``/method`` are amex's protobuf messages (:mod:`amex.log.flat_proto`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import foxglove
import numpy as np
from foxglove.messages import JointState, JointStates, Timestamp

from amex.log.batch import Kept, StepBatch
from amex.log.constants import LogConstants
from amex.log.method_topic import MethodTopic


class StepMessages(NamedTuple):
    """A batch's per-step messages (:meth:`StepTopics.messages`).

    Attributes:
        logs: the ``log`` of each per-step topic's channel, in the log's order: ``/tf``,
            ``/joint_states``, ``/tcp``, ``/goal``, ``/command``, ``/method``.
        columns: per topic of :attr:`logs`, each step's message (bytes); the logger writes a
            step's in this order and then the scene's.
        times: per step, its time [s].
        stamps: per step, its time [ns] (every message's log time and timestamp).
        tcps: per step, the TCP position [m] (the scene's executed path).
    """

    logs: tuple[Any, ...]
    columns: tuple[list[bytes], ...]
    times: list[float]
    stamps: list[int]
    tcps: list[list[float]]


class StepTopics:
    """The per-step topics of one log (module notes).

    Args:
        context: the log's context (``/method`` is created in it at the first step).
        constants: the run's :class:`~amex.log.constants.LogConstants`.
        channels: the channels of ``/tf``, ``/joint_states``, ``/tcp``, ``/goal`` and
            ``/command`` (``foxglove.Channel``), created by the logger in its topic order.
        fresh: the method's :attr:`~amex.methods.base.Method.fresh_steps`: its steps'
            ``internals()`` are kept as they are, without a snapshot.

    Attributes:
        method_channel: ``/method``'s channel once the first step made it, else None.
        values_are_internals: True once :meth:`method_values` would return a step's
            ``internals()`` as they are (a fresh method's, after the first step): the logger
            then keeps them without the call.
    """

    def __init__(
        self,
        context: foxglove.Context,
        constants: LogConstants,
        channels: dict[str, Any],
        *,
        fresh: bool = False,
    ) -> None:
        self._fresh = fresh
        self._context = context
        self._constants = constants
        self._channels = {topic: channel.base for topic, channel in channels.items()}
        self._method = MethodTopic()  # /method's schema, at the first step
        self.method_channel: foxglove.Channel | None = None
        self.values_are_internals = False

    def method_values(self, t: float, internals: dict[str, Any]) -> dict[str, Any]:
        """What ``/method``'s message of a step needs: numbers, flags, texts, small arrays.

        The first step makes the channel and its schema from its ``internals()``
        (:class:`amex.log.method_topic.MethodTopic`). The message is encoded by
        :meth:`messages`, with the batch (:meth:`~amex.log.method_topic.MethodTopic.snapshot`).
        """
        method = self._method
        if method.kinds is None:
            self.method_channel = method.schema(t, internals).channel("/method", self._context)
            self._channels["/method"] = self.method_channel.base
            self.values_are_internals = self._fresh
        return internals if self._fresh else method.snapshot(internals)

    def messages(self, batch: StepBatch, k: int, kept: list[Kept]) -> StepMessages:
        """The messages of the first ``k`` rows of ``batch`` (and their ``kept``), encoded.

        Each kind for all the rows in a row (the batch's compiled encoders, then ``/method``),
        so that each loop runs warm, and kept as one column per topic: the logger adds the
        scene's and writes them a step at a time (class notes).
        """
        encoded = batch.encode(k)
        data = encoded.data
        times, stamps = batch.t[:k].tolist(), batch.ns[:k].tolist()
        channels = self._channels
        if encoded.joints is not None:
            joints = encoded.joints.tolist()
            tfs = [data[a:b] for a, b, _ in joints]
            states = [data[b:c] for _, b, c in joints]
        else:
            pairs = [
                self._joints_generic(batch.q[i], batch.v[i], batch.qacc[i], batch.tau[i], ns)
                for i, ns in enumerate(stamps)
            ]
            tfs, states = [tf for tf, _ in pairs], [state for _, state in pairs]
        numbers = encoded.numbers.tolist()
        tcps = [data[a:b] for a, b, _, _ in numbers]
        goals = [data[b:c] for _, b, c, _ in numbers]
        commands = [
            data[c:d] if step.command is None else step.command
            for (_, _, c, d), step in zip(numbers, kept, strict=True)
        ]
        snaps = [step.method for step in kept]
        methods = self._method.encode_snapshots(times, snaps, raw=self._fresh)
        logs = tuple(channels[topic].log for topic in _TOPICS)
        columns = (tfs, states, tcps, goals, commands, methods)
        return StepMessages(logs, columns, times, stamps, batch.y[:k, :3].tolist())

    def _joints_generic(
        self, q: np.ndarray, v: np.ndarray, qacc: np.ndarray, tau: np.ndarray, ns: int
    ) -> tuple[bytes, bytes]:
        """``/tf`` and ``/joint_states`` as the SDK's objects (a transform of no compiled kind)."""
        stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)  # sim_stamp(t)
        tf = self._constants.links.message(q, stamp).encode()
        qs, vs, qdd, taus = q.tolist(), v.tolist(), qacc.tolist(), tau.tolist()
        joints = [
            JointState(name=n, position=a, velocity=b, acceleration=c, effort=d)
            for n, a, b, c, d in zip(self._constants.joint_names, qs, vs, qdd, taus, strict=False)
        ]
        return tf, JointStates(timestamp=stamp, joints=joints).encode()


#: The per-step topics, in the order a step writes them (:attr:`StepMessages.logs`).
_TOPICS = ("/tf", "/joint_states", "/tcp", "/goal", "/command", "/method")
