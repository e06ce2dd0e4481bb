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
        steps: per step, its messages in the log's order, each as (its channel's ``log``, its
            bytes); the logger appends the scene's.
        times: per step, its time [s].
        stamps: per step, its time [ns] (every message's log time and timestamp).
        tcps: per step, the TCP position [m] (the scene's executed path).
    """

    steps: list[list[tuple[Any, bytes]]]
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
        return internals if self._fresh else method.snapshot(internals)

    def messages(self, batch: StepBatch, k: int, kept: list[Kept]) -> StepMessages:
        """The messages of the first ``k`` rows of ``batch`` (and their ``kept``), encoded.

        Each kind for all the rows in a row (the batch's compiled encoders, then ``/method``),
        so that each loop runs warm; the logger adds the scene's and writes them (class notes).
        """
        encoded = batch.encode(k)
        data = encoded.data
        times, stamps = batch.t[:k].tolist(), batch.ns[:k].tolist()
        numbers = encoded.numbers.tolist()
        channels = self._channels
        tf, joint_states = channels["/tf"].log, channels["/joint_states"].log
        tcp, goal, command = channels["/tcp"].log, channels["/goal"].log, channels["/command"].log
        steps: list[list[tuple[Any, bytes]]] = []
        if encoded.joints is not None:
            for a, b, c in encoded.joints.tolist():
                steps.append([(tf, data[a:b]), (joint_states, data[b:c])])
        else:
            for i in range(k):
                q, v, qacc, tau = batch.q[i], batch.v[i], batch.qacc[i], batch.tau[i]
                steps.append(self._joints_generic(q, v, qacc, tau, stamps[i]))
        for out, (a, b, c, d), step in zip(steps, numbers, kept, strict=True):
            out += (
                (tcp, data[a:b]),
                (goal, data[b:c]),
                (command, data[c:d] if step.command is None else step.command),
            )
        method = channels.get("/method")
        if method is not None:
            log = method.log
            snaps = [step.method for step in kept]
            encoded_method = self._method.encode_snapshots(times, snaps, raw=self._fresh)
            for out, data in zip(steps, encoded_method, strict=True):
                out.append((log, data))
        return StepMessages(steps, times, stamps, batch.y[:k, :3].tolist())

    def _joints_generic(
        self, q: np.ndarray, v: np.ndarray, qacc: np.ndarray, tau: np.ndarray, ns: int
    ) -> list[tuple[Any, bytes]]:
        """``/tf`` and ``/joint_states`` as the SDK's objects (a transform of no compiled kind)."""
        stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)  # sim_stamp(t)
        tf = self._constants.links.message(q, stamp).encode()
        qs, vs, qdd, taus = q.tolist(), v.tolist(), qacc.tolist(), tau.tolist()
        joints = [
            JointState(name=n, position=a, velocity=b, acceleration=c, effort=d)
            for n, a, b, c, d in zip(self._constants.joint_names, qs, vs, qdd, taus, strict=False)
        ]
        message = JointStates(timestamp=stamp, joints=joints)
        channels = self._channels
        return [(channels["/tf"].log, tf), (channels["/joint_states"].log, message.encode())]
