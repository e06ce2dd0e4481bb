"""Per-episode MCAP logs that Foxglove opens as a 3-D scene with plots (foxglove-sdk writer).

One file per episode, one ``foxglove.Context`` per file. Every outer step (100 Hz) writes, with the
simulation time both as the MCAP log time and as the timestamp inside each message (Foxglove's 3D
panel looks transforms up by the latter):

==================== ========================= ==================================================
topic                schema                    content
==================== ========================= ==================================================
``/tf``              foxglove.FrameTransforms  ``world -> panda_link0`` and one transform per URDF
                                               joint, parent/child = the URDF link names
``/joint_states``    foxglove.JointStates      q, q_dot, q_ddot, tau (position, velocity,
                                               acceleration, effort)
``/scene/world``     foxglove.SceneUpdate      goal (success sphere) and obstacle spheres, when
                                               they moved > 1 mm, else once a second
``/scene/path``      foxglove.SceneUpdate      executed TCP path (line, every ``path_every`` steps)
``/scene/plan``      foxglove.SceneUpdate      the method's current plan: an (k, 3) array under
                                               ``internals()["plan"]`` (<= 100 points shown)
``/scene/reference`` foxglove.SceneUpdate      the reference plan's TCP path (every second)
``/tcp``             protobuf                  TCP position, z-axis, velocity, distance to goal
``/goal``            protobuf                  goal position and distance to it
``/command``         protobuf                  the command: y*, y_dot* (and q*, q_dot* if any)
``/method``          protobuf                  the method's ``internals()`` (numbers, flags, texts,
                                               small number arrays; schema from the first step)
``/reference``       JSON                      the reference plan: ``dt``, ``duration`` and
                                               ``samples`` [{t, position, axis}] (once, t = 0)
``/episode``         JSON                      the episode's result (once, at the end)
==================== ========================= ==================================================

The scene topics are :class:`amex.log.scene.SceneChannels`' (its colours are the palette's: the
executed path in the method's colour, the ``method`` of the metadata).

Every JSON schema declares all the fields its messages carry, in the form browser viewers accept
(:func:`amex.log.messages.viewer_schema_problems`: no arrays of arrays, every array has ``items``).

MCAP metadata records: ``episode`` (the caller's metadata: task, method, env, seed, ...),
``scenario``, ``robot``, ``log`` (written first) and ``outcome`` (written last: the result, or
why the log ended early). Values are JSON texts.

Cost (issue #29, ``python -m amex.app.bench_log``): the messages are encoded without the SDK's
message objects (:mod:`amex.log.wire`, :mod:`amex.log.scene_wire`: the same bytes). A step only
keeps what its messages need (:meth:`~amex.log.batch.StepBatch.add`, a few copies, and
``/method``'s snapshot; neither the command's nor the internals' copies for a method of
:attr:`~amex.methods.base.Method.fresh_steps`); every :data:`BATCH` steps, each kind of
message is encoded for the whole batch in turn and then all are written in one loop of the
SDK's calls, so that each loop runs warm instead of once between every 10 inner steps. A plan
given as a :class:`~amex.core.lazy.LazyRows` is computed there, at the knots drawn alone. What
the run shares (link transforms, ``/reference``, the robot's record, the schemas) is made once
per run (:mod:`amex.log.constants`); the scene's world update is decided and encoded for the
batch in two compiled calls, and the executed path's points are encoded once, as they come.
What remains is mostly the SDK's writing (~2 us per message, six to nine messages a step, its lz4
chunks included) and the steps' values taken between the inner steps, where they run cold
(docs/results/speed.md gives the measured cost).

Crash safety: the file is written as ``<path>.part`` and renamed to ``<path>`` when closed, so a
finished log never has the suffix, and no existing file is ever overwritten: an existing
``<path>`` or ``<path>.part`` (a rerun, or a resumed run's interrupted episode) is renamed to
``<stem>.old<n>...`` with a warning. Chunks are 64 KiB, lz4-compressed (``log_compression``:
zstd or none): after SIGKILL at most the last chunk (~0.5 s of simulation) and the steps kept
since the last batch (< 1 s, :data:`BATCH`) are lost, and :func:`amex.log.reader.read_log`
recovers the rest. A write that fails stops the episode (:class:`~amex.core.errors.WriteError`)
at the end of the batch it was in. The log
is closed in ``__exit__`` and on SIGTERM (SLURM's way of stopping a job), the kept steps
written first: a handler is installed while the log is open (main thread only), finishes the
file, restores the previous handler and re-delivers the signal to it.
"""

from __future__ import annotations

import bisect
import functools
import os
import signal
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import foxglove
import numpy as np
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from foxglove.messages import FrameTransforms, JointStates

from amex.core.errors import LogError, LogExistsError, WriteError
from amex.core.version import __version__
from amex.log import flat_proto as P
from amex.log import messages as M
from amex.log.batch import StepBatch
from amex.log.constants import log_constants
from amex.log.files import WriteFailures, failure_cause, set_aside
from amex.log.frames import WORLD_FRAME
from amex.log.frames import LinkTransforms as LinkTransforms  # re-exported (tests, callers)
from amex.log.scene import SceneChannels
from amex.log.step_topics import StepTopics
from amex.log.wire import protobuf_channel

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel
    from amex.sim.loop import StepRecord
    from amex.sim.metrics import EpisodeResult
    from amex.sim.scenario import Scenario

CHUNK_SIZE = 64 * 1024  # [bytes] uncompressed chunk target: what a SIGKILL can lose
PART_SUFFIX = ".part"
#: The chunks' compressions (``log_compression``): lz4 is the default. Measured on 2026-12-07
#: (Zen 4; the DMP and AMEX on Task 1, 2 rounds of 6 environments): zstd costs ~1 point of an
#: episode more than lz4 for files 13-17 % smaller (lz4's are 14-20 % larger: 96-194 kB per
#: simulated second against 81-169); none ~1.5 points less than lz4, files 1.7-2.2 times lz4's.
COMPRESSIONS: dict[str, MCAPCompression | None] = {
    "lz4": MCAPCompression.Lz4,
    "zstd": MCAPCompression.Zstd,
    "none": None,
}
DEFAULT_COMPRESSION = "lz4"  # RunConfig.log_compression's default (amex.experiment.config)
COMPRESSION_LEVEL = 1  # fast zstd: level 3 saves ~3-5 % of the size for ~20 % more time
#: Outer steps kept before they are written (1 s of simulation at 100 Hz). 100 rather than 50:
#: each batch's fixed costs (a compiled call per kind, a concatenation per array) are paid half
#: as often, 0.5-1 point of an episode less (2026-12-07, AMEX and CR on Task 2, 6 environments
#: x 3 rounds); a SIGKILL can lose 0.5 s more.
BATCH = 100


def write_options(compression: str = DEFAULT_COMPRESSION) -> MCAPWriteOptions:
    """The SDK's MCAP options of a log: chunks of :data:`CHUNK_SIZE`, no threads.

    Made once per compression (~40 us each) and shared: the SDK copies them into each writer.

    Args:
        compression: a key of :data:`COMPRESSIONS` (zstd at :data:`COMPRESSION_LEVEL`).

    Raises:
        ValueError: for another ``compression``.
    """
    if compression not in COMPRESSIONS:
        raise ValueError(f"invalid compression={compression!r}; valid: {', '.join(COMPRESSIONS)}")
    return _write_options(compression)


@functools.lru_cache(maxsize=len(COMPRESSIONS))
def _write_options(compression: str) -> MCAPWriteOptions:
    return MCAPWriteOptions(
        compression=COMPRESSIONS[compression],
        chunk_size=CHUNK_SIZE,
        compression_threads=0,
        compression_level=COMPRESSION_LEVEL if compression == "zstd" else 0,
        profile="",
    )


class EpisodeLogger:
    """Recorder (see :class:`amex.sim.episode.Recorder`) writing one episode as an MCAP file.

    Use as a context manager around :func:`amex.sim.episode.run_episode`; the file appears at
    ``path`` when the context exits (or on SIGTERM), and ``<path>.part`` holds it until then.

    Args:
        path: the log file to create (parent directories are created); an existing file of that
            name, or its ``.part``, is kept under another name (:func:`set_aside`).
        robot: the arm (URDF link names for the transforms, joint names).
        plan: the reference plan (drawn as a line; its ``y`` and ``dt`` are logged once).
        scenario: the environment (goal and obstacle motion, obstacle radii).
        metadata: the episode's identity and configuration (JSON-able values), written as the
            MCAP metadata record ``episode``.
        path_every: outer steps between updates of the executed-path and plan lines.
        max_line_points: plan lines are decimated to at most this many points.
        compression: how the chunks are compressed, a key of :data:`COMPRESSIONS`.
        fresh_steps: the method's :attr:`~amex.methods.base.Method.fresh_steps`: its steps'
            command and ``internals()`` are kept without copies.
    """

    def __init__(
        self,
        path: Path | str,
        robot: RobotModel,
        plan: ReferencePlan,
        scenario: Scenario,
        metadata: dict[str, Any],
        *,
        path_every: int = 5,
        max_line_points: int = 100,
        compression: str = DEFAULT_COMPRESSION,
        fresh_steps: bool = False,
    ) -> None:
        options = write_options(compression)  # first: a bad value makes no file
        self.path = Path(path)
        self.part_path = self.path.with_name(self.path.name + PART_SUFFIX)
        for existing in (self.path, self.part_path):
            if existing.exists():
                set_aside(existing)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise LogError(f"cannot create the log directory {self.path.parent}: {e}") from e
        self._constants = log_constants(robot, plan)
        self._path_every = max(1, int(path_every))
        self._steps = 0
        self._t = 0.0
        self._outcome_written = False
        self._closed = True
        self._last_tcp: tuple[float, float, float] | None = None

        self._failures = WriteFailures()
        self._failures.attach()
        self._context = foxglove.Context()
        try:
            self._writer = foxglove.open_mcap(
                self.part_path, context=self._context, writer_options=options
            )
        except Exception as e:  # foxglove raises its own error types for I/O failures
            self._failures.detach()
            raise LogError(f"cannot create the log file {self.part_path}: {e}") from e
        self._closed = False
        ctx = self._context
        # the typed channels' topics and schemas, written with bytes encoded here (amex.log.wire)
        self._tf = protobuf_channel("/tf", FrameTransforms, ctx)
        self._joint_states = protobuf_channel("/joint_states", JointStates, ctx)
        self._scene = SceneChannels(
            ctx,
            np.asarray(plan.y)[:, :3],
            scenario.obstacle_radii,
            obstacles_move=bool(np.any(scenario.obstacle_velocity)),
            method=str(metadata.get("method", "")),
            max_line_points=max(2, int(max_line_points)),
        )
        self._numbers = {  # amex's own protobuf messages (amex.log.flat_proto)
            topic: schema.channel(topic, ctx)
            for topic, schema in (("/tcp", P.TCP), ("/goal", P.GOAL), ("/command", P.COMMAND))
        }
        self._json = {
            topic: foxglove.Channel(topic, schema=schema, message_encoding="json", context=ctx)
            for topic, schema in M.json_channel_schemas(int(np.shape(plan.y)[1])).items()
        }
        step_channels = {"/tf": self._tf, "/joint_states": self._joint_states, **self._numbers}
        self._topics = StepTopics(ctx, self._constants, step_channels, fresh=fresh_steps)
        self._batch = StepBatch(  # steps kept, not yet written
            BATCH, robot.nv, np.shape(plan.y)[1], self._constants.encoding, fresh=fresh_steps
        )
        self._previous_handler: Any = None
        self._install_sigterm()
        try:
            self._write_header(robot, plan, scenario, metadata)
        except BaseException:
            self.close({"status": "error", "error": "could not write the log header"})
            raise

    # -- lifecycle -------------------------------------------------------------------------

    def __enter__(self) -> EpisodeLogger:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
            return
        try:
            self.close({"status": "interrupted", "error": f"{exc_type.__name__}: {exc}"})
        except WriteError:
            if not isinstance(exc, WriteError):
                raise  # the log failed too: that is the cause to report
            # else: the episode already stopped for this failure

    @property
    def closed(self) -> bool:
        """True once the file is finished (renamed to :attr:`path`)."""
        return self._closed

    def close(self, outcome: dict[str, Any] | None = None) -> None:
        """Finish the file and rename it to :attr:`path` (idempotent).

        Args:
            outcome: written as the ``outcome`` metadata record if :meth:`finish` did not write
                one (e.g. ``{"status": "interrupted", ...}``).
        """
        if self._closed:
            return
        self._restore_sigterm()
        try:
            try:
                self._flush()  # the steps kept since the last batch
            except WriteError:
                pass  # reported below, from the same cause
            finally:
                self._closed = True
            if not self._outcome_written and not self._failures.cause:
                info = {"status": "incomplete", "steps": self._steps, "t": self._t}
                info.update(outcome or {})
                self._write_metadata("outcome", info)
            for channel in self._all_channels():
                channel.close()
            try:
                self._writer.close()
            except Exception as e:  # the SDK's error for a write that failed at the end
                self._failures.cause = self._failures.cause or failure_cause(str(e))
        finally:
            self._failures.detach()
        if self._failures.cause:  # a cut log keeps its .part name: it is no finished episode
            raise WriteError(self.part_path, self._failures.cause)
        if self.path.exists():  # appeared meanwhile: keep both, say where the log is
            raise LogExistsError(
                f"log file {self.path} appeared while logging; the log is in {self.part_path}"
            )
        os.replace(self.part_path, self.path)

    def _all_channels(self) -> list[Any]:
        method = self._topics.method_channel
        return [
            self._tf,
            self._joint_states,
            *self._scene.channels(),
            *self._numbers.values(),
            *self._json.values(),
            *([method] if method is not None else []),
        ]

    def _install_sigterm(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return  # signal handlers can only be set from the main thread
        self._previous_handler = signal.getsignal(signal.SIGTERM)
        signal.signal(signal.SIGTERM, self._on_sigterm)

    def _restore_sigterm(self) -> None:
        if self._previous_handler is None:
            return
        previous, self._previous_handler = self._previous_handler, None
        if signal.getsignal(signal.SIGTERM) == self._on_sigterm:
            signal.signal(signal.SIGTERM, previous)

    def _on_sigterm(self, signum: int, frame: Any) -> None:
        previous = self._previous_handler
        self.close({"status": "terminated", "signal": "SIGTERM"})
        if callable(previous):
            previous(signum, frame)
        elif previous != signal.SIG_IGN:  # default action: die of SIGTERM, as without us
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGTERM)

    # -- content ---------------------------------------------------------------------------

    def _write_metadata(self, name: str, values: dict[str, Any]) -> None:
        self._writer.write_metadata(name, M.metadata_record(values))

    def _write_header(
        self, robot: RobotModel, plan: ReferencePlan, scenario: Scenario, metadata: dict[str, Any]
    ) -> None:
        self._write_metadata("episode", dict(metadata))
        self._write_metadata(
            "scenario",
            {
                "task": scenario.task,
                "env": scenario.env,
                "seed": scenario.seed,
                "goal_start": scenario.goal_start,
                "goal_velocity": scenario.goal_velocity,
                "goal_stop_time": scenario.goal_stop_time,
                "goal_axis": scenario.goal_axis,
                "obstacle_start": scenario.obstacle_start,
                "obstacle_velocity": scenario.obstacle_velocity,
                "obstacle_radii": scenario.obstacle_radii,
            },
        )
        self._writer.write_metadata("robot", self._constants.robot_record)
        self._write_metadata(
            "log",
            {
                "amex_version": __version__,
                "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "time": "simulation time [s] since the episode start",
                "world_frame": WORLD_FRAME,
            },
        )
        self._json["/reference"].base.log(self._constants.reference_json, 0)
        self._scene.publish_world(0.0, scenario.goal_at(0.0), scenario.obstacles_at(0.0))
        self._scene.publish_reference(0.0)

    def record(self, step: StepRecord) -> None:
        """Log one outer step (see the module docstring for what goes where).

        The step is kept (:meth:`~amex.log.batch.StepBatch.add`) and written with the next
        :data:`BATCH` - 1 steps, or at :meth:`finish` or :meth:`close` (module notes).
        """
        if self._closed:
            return
        batch, internals = self._batch, step.internals
        plan = None  # as given: a lazy plan is computed when the batch draws it (amex.log.scene)
        if (self._steps + batch.count) % self._path_every == 0:
            plan = dict.get(internals, "plan")
        topics = self._topics
        if not topics.values_are_internals:  # else the internals themselves (a fresh method)
            internals = topics.method_values(step.t, internals)
        if batch.add(step, internals, plan) >= BATCH:
            self._flush()

    def _flush(self) -> None:
        """Write the kept steps, in order, every topic of a step before the next step's.

        Encoded first, a kind at a time for the whole batch (the per-step topics, then the
        plans, then the rest of the scene), and then written in one loop of the SDK's calls:
        each loop runs warm (issue #29; interleaved, the same calls cost up to several times
        their time in a loop).
        """
        batch, scene, every = self._batch, self._scene, self._path_every
        count, kept = batch.fill(), batch.kept
        batch.clear()  # first: a SIGTERM's close() meanwhile writes none of them twice
        if count:
            encoded = self._topics.messages(batch, count, kept)
            times, stamps = encoded.times, encoded.stamps
            first = self._steps
            drawn = range((-first) % every, count, every)  # the steps that draw path and plan
            updates = scene.plan_updates([times[i] for i in drawn], [kept[i].plan for i in drawn])
            world_log, path_log = scene.world.base.log, scene.path.base.log
            plan_log, reference_log = scene.plan.base.log, scene.reference.base.log
            worlds = scene.world_updates(
                times, batch.ns[:count], batch.goal[:count], [step.obstacles for step in kept]
            )
            # per step, its scene messages in the log's order (world, path, plan, reference)
            extras: list[list[tuple[Any, bytes]] | None] = [None] * count
            for i, update in worlds.items():
                extras[i] = [(world_log, update)]
            tcps = encoded.tcps
            for i, plan in zip(drawn, updates, strict=True):
                tcp = tcps[i]
                scene.add_path_point(tcp[0], tcp[1], tcp[2])
                path = scene.path_update(times[i])
                if path is not None:
                    _append(extras, i, (path_log, path))
                if plan is not None:
                    _append(extras, i, (plan_log, plan))
            i = bisect.bisect_left(times, scene.next_reference)  # (times increase)
            while i < count:
                _append(extras, i, (reference_log, scene.reference_update(times[i])))
                i = bisect.bisect_left(times, scene.next_reference, i + 1)
            tf, joint_states, tcp_log, goal, command, method = encoded.logs
            for ns, a, b, c, d, e, f, extra in zip(stamps, *encoded.columns, extras, strict=True):
                tf(a, ns)
                joint_states(b, ns)
                tcp_log(c, ns)
                goal(d, ns)
                command(e, ns)
                method(f, ns)
                if extra is not None:
                    for log, data in extra:
                        log(data, ns)
            self._steps = first + count
            self._t = times[-1]
            tcp = encoded.tcps[-1]
            self._last_tcp = (tcp[0], tcp[1], tcp[2])
        if self._failures.cause:  # stop the episode: the rest of the log could not be written
            raise WriteError(self.part_path, self._failures.cause)

    def finish(self, result: EpisodeResult) -> None:
        """Write the result: the last path update, ``/episode`` and the ``outcome`` record."""
        if self._closed:
            return
        self._flush()
        t = max(self._t, float(result.final_time))
        if self._last_tcp is not None and (self._steps - 1) % self._path_every:
            self._scene.add_path_point(*self._last_tcp)
        self._scene.publish_path(t)
        row = result.as_row()
        status = "failed" if row.get("failure") else "finished"
        self._json["/episode"].base.log(M.dumps({"t": t, "status": status, **row}), round(t * 1e9))
        self._write_metadata("outcome", {"status": status, "steps": self._steps, **row})
        self._outcome_written = True


def _append(
    extras: list[list[tuple[Any, bytes]] | None], i: int, message: tuple[Any, bytes]
) -> None:
    """Add ``message`` to step ``i``'s scene messages (a list made at the first)."""
    out = extras[i]
    if out is None:
        extras[i] = [message]
    else:
        out.append(message)
