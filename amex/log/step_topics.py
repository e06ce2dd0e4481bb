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

from collections.abc import Iterator
from typing import Any

import foxglove
import numpy as np
from foxglove.messages import JointState, JointStates, Timestamp

from amex.log.batch import Kept, StepBatch
from amex.log.constants import LogConstants
from amex.log.method_topic import Captured, MethodTopic


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
        self._method = MethodTopic()  # /method's schema, at the first step
        self.method_channel: foxglove.Channel | None = None

    def method_values(self, t: float, internals: dict[str, Any]) -> Captured:
        """What ``/method``'s message of a step needs: numbers, flags, texts, small arrays.

        The first step makes the channel and its schema from its ``internals()``
        (:class:`amex.log.method_topic.MethodTopic`). The message is encoded by :meth:`write`,
        with the batch (:meth:`~amex.log.method_topic.MethodTopic.capture`).
        """
        method = self._method
        if method.kinds is None:
            self.method_channel = method.schema(t, internals).channel("/method", self._context)
            self._channels["/method"] = self.method_channel.base
        return method.capture(internals)

    def write(
        self, batch: StepBatch, k: int, kept: list[Kept]
    ) -> Iterator[tuple[float, list[float]]]:
        """Log the first ``k`` rows of ``batch`` (and their ``kept``) in order.

        After each step, yields its time [s] and TCP position [m], for the scene.
        """
        encoded = batch.encode(k)
        data = encoded.data
        times, stamps = batch.t[:k].tolist(), batch.ns[:k].tolist()
        tcps = batch.y[:k, :3].tolist()
        numbers = encoded.numbers.tolist()
        joints = encoded.joints.tolist() if encoded.joints is not None else None
        channels = self._channels
        tf, joint_states = channels["/tf"], channels["/joint_states"]
        tcp, goal, command = channels["/tcp"], channels["/goal"], channels["/command"]
        method, encode = channels.get("/method"), self._method.encode_captured
        for i in range(k):
            ns, step = stamps[i], kept[i]
            if joints is not None:
                a, b, c = joints[i]
                tf.log(data[a:b], ns)
                joint_states.log(data[b:c], ns)
            else:
                self._log_joints_generic(ns, batch.q[i], batch.v[i], batch.qacc[i], batch.tau[i])
            a, b, c, d = numbers[i]
            tcp.log(data[a:b], ns)
            goal.log(data[b:c], ns)
            command.log(data[c:d] if step.command is None else step.command, ns)
            if method is not None:
                method.log(encode(times[i], step.method), ns)
            yield times[i], tcps[i]

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
        message = JointStates(timestamp=stamp, joints=joints)
        self._channels["/joint_states"].log(message.encode(), ns)
