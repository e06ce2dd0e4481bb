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
from typing import TYPE_CHECKING, Any, NamedTuple

import foxglove
import numpy as np
from foxglove.messages import JointState, JointStates, Timestamp

from amex.log import messages as M
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


_TCP_FIELDS = [("t", 0), ("position", 3), ("axis", 3), ("velocity", 3), ("distance_to_goal", 0)]
_GOAL_FIELDS = [("t", 0), ("position", 3), ("distance", 0)]


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
        self._tcp_json = M.json_template(_TCP_FIELDS)
        self._goal_json = M.json_template(_GOAL_FIELDS)
        self._numbers_json: dict[tuple[bool, ...], str] = {}  # /tcp, /goal, /command in one
        self._command_json: dict[tuple[bool, ...], str] = {}
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
        """``/tcp``, ``/goal`` and ``/command``, formatted by one %-template."""
        values = [t, *y, *yd[:3], distance, t, *goal, distance, t]
        present = []
        for part in command:
            present.append(part is not None)
            if part is not None:
                values += part.tolist()
        key = tuple(present)
        template = self._numbers_json.get(key)
        if template is None:
            command_json = self._command_template(command)
            template = "\n".join((self._tcp_json, self._goal_json, command_json))
            self._numbers_json[key] = template
        if not math.isfinite(sum(values)):  # NaN/inf is not JSON: null (slow path, rare)
            self._log_numbers("/tcp", self._tcp_json, (t, *y, *yd[:3], distance), ns)
            self._log_numbers("/goal", self._goal_json, (t, *goal, distance), ns)
            self._log_command(t, command, ns)
            return
        tcp, goal_text, command_text = (template % tuple(values)).encode().split(b"\n")
        channels = self._channels
        channels["/tcp"].log(tcp, ns)
        channels["/goal"].log(goal_text, ns)
        channels["/command"].log(command_text, ns)

    def _log_method(self, t: float, internals: Any, ns: int) -> None:
        """``/method``: the numbers, flags, texts and small number arrays of ``internals()``.

        The channel and its schema are made at the first step from the values then
        (:class:`amex.log.method_topic.MethodTopic`).
        """
        method = self._method
        if method.kinds is None:
            schema = method.schema(t, internals)
            self.method_channel = foxglove.Channel("/method", schema=schema, context=self._context)
            self._channels["/method"] = self.method_channel.base
        self._channels["/method"].log(method.encode(t, internals), ns)

    def _command_template(self, command: Any) -> str:
        """The %-template of ``/command`` for the parts ``command`` has (made at the first one)."""
        present = tuple(part is not None for part in command)
        template = self._command_json.get(present)
        if template is None:
            names = ("y_star", "yd_star", "q_star", "qd_star")
            fields = [("t", 0)]
            fields += [(k, len(p)) for k, p in zip(names, command, strict=False) if p is not None]
            template = self._command_json[present] = M.json_template(fields)
        return template

    def _log_command(self, t: float, command: Any, ns: int) -> None:
        """y*, y_dot* (and q*, q_dot*): whichever parts the command has."""
        parts = [p.tolist() for p in command if p is not None]
        template = self._command_template(command)
        self._log_numbers("/command", template, (t, *(x for p in parts for x in p)), ns)

    def _log_numbers(self, topic: str, template: str, values: tuple[float, ...], ns: int) -> None:
        if math.isfinite(sum(values)):
            data = (template % values).encode()
        else:  # NaN/inf is not JSON: null instead (slow path, rare)
            data = (
                template.replace(M.NUM, "%s")
                % tuple(repr(v) if math.isfinite(v) else "null" for v in values)
            ).encode()
        self._channels[topic].log(data, ns)
