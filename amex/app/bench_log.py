"""What ``log=full`` costs an episode: the same episodes with and without the MCAP log (issue #29).

:func:`log_overhead` runs environments of a task with a method exactly as a run builds them
(:func:`amex.experiment.runner.setup`, then :func:`~amex.experiment.runner.run_setup`), each one
without and with a log file (a temporary directory), in turn, ``rounds`` times (the medians of
its rounds: ``--rounds``, 3 by default), so that both see the same load of the machine. Each
episode is timed whole, set-up of the method and the logger and the log's finish included, in
thread CPU time (``time.thread_time_ns``) and wall time. The first environment is run once
before, unlogged and logged, so that caches (reference plan, Numba, the URDF's joints) are warm;
then the heap is frozen, as ``amex-run`` freezes it once its episodes are set up
(:func:`amex.app.heap.settle`). Without that, the cyclic collector's full collections, which the
log's allocations trigger and an unlogged episode does not, walk the whole set-up: on 2026-12-06,
one every ~6 logged episodes of the DMP on Task 1, ~48 ms each, a cost no run pays. The log's
cost includes the method's ``internals()``, which the episode loop calls only for a recorder.

Nothing here asserts a time. ``python -m amex.app.bench_log --tasks 1 2 3 4 --methods amex dmp cr``
prints, per task and method, the median and p95 of the per-episode overhead ``logged / plain - 1``,
and beside it two floors, over the plain episode: the SDK writing the same log file again alone
(:func:`sdk_floor`), and the same episode run a third time with a recorder that writes the logged
episode's messages, already encoded, through the SDK a batch of steps at a time, as the logger
does, taking each step's values as a logger must (:class:`ReplayRecorder`): what a logger of
these messages through the SDK, written a batch at a time, costs inside the episode before
encoding anything.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, NamedTuple  # noqa: E402

import numpy as np  # noqa: E402

from amex.app.argparsing import OneLineParser  # noqa: E402


class LogOverhead(NamedTuple):
    """Per-episode times of the same environments, plain and logged [s] (shape (envs,) each).

    ``floor_cpu``: the thread CPU time of the SDK writing the logged episode's file again
    alone (:func:`sdk_floor`); ``replay_cpu``: the episode's, with :class:`ReplayRecorder`
    writing that file's messages again.
    """

    plain_cpu: np.ndarray
    logged_cpu: np.ndarray
    plain_wall: np.ndarray
    logged_wall: np.ndarray
    floor_cpu: np.ndarray
    replay_cpu: np.ndarray

    def floor(self) -> np.ndarray:
        """The SDK's floor over the plain episode, ``floor / plain`` per episode [-]."""
        return self.floor_cpu / self.plain_cpu

    def replay(self) -> np.ndarray:
        """The replaying recorder's cost, ``replayed / plain - 1`` per episode [-]."""
        return self.replay_cpu / self.plain_cpu - 1.0

    def overhead(self, clock: str = "thread") -> np.ndarray:
        """``logged / plain - 1`` per episode, in ``clock`` (``thread`` or ``wall``) [-]."""
        if clock not in ("thread", "wall"):
            raise ValueError(f"invalid clock={clock!r}; valid: thread, wall")
        if clock == "thread":
            return self.logged_cpu / self.plain_cpu - 1.0
        return self.logged_wall / self.plain_wall - 1.0


def sdk_floor(path: Path, out: Path) -> float:
    """Thread CPU [s] of the SDK writing the log ``path`` again, alone, to ``out``.

    The log's schemas, channels, messages and metadata records are read first (the mcap
    library's reader, untimed); then, timed, what the library must do for that log whatever
    writes it: a context, the file with the logs' options
    (:func:`amex.log.writer.write_options`), the channels, every message in its order, the
    metadata records, the close. What ``log=full`` spends beyond this is amex's: taking the
    steps' values, encoding the messages, the scene, and the caches they cool.
    """
    messages, records, compression = _read_log(path)
    cpu = time.thread_time_ns()
    # the context lives to the close
    context, writer, channels = _open_again(out, messages, compression)
    for name, values in records[:1]:  # the header (the rest are written last, as the logs do)
        writer.write_metadata(name, values)
    for _, channel, message in messages:
        channels[channel.id].log(message.data, message.log_time)
    for name, values in records[1:]:
        writer.write_metadata(name, values)
    for base in channels.values():
        base.close()
    writer.close()
    del context
    return (time.thread_time_ns() - cpu) * 1e-9


def _read_log(path: Path) -> tuple[list[Any], list[tuple[str, dict[str, str]]], str]:
    """A log's ``(schema, channel, message)`` in the order written, records and compression.

    The metadata records in their order, and the chunks' compression (a key of
    :data:`amex.log.writer.COMPRESSIONS`).
    """
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        reader = make_reader(f)
        messages = list(reader.iter_messages(log_time_order=False))
        records = [(m.name, m.metadata) for m in reader.iter_metadata()]
        summary = reader.get_summary()
    chunks = summary.chunk_indexes if summary is not None else []
    compression = (chunks[0].compression if chunks else "") or "none"
    return messages, records, compression


def _open_again(
    out: Path, messages: list[Any], compression: str
) -> tuple[Any, Any, dict[int, Any]]:
    """The SDK's context, MCAP writer (a log's options) and channels of ``messages``."""
    import foxglove

    from amex.log.writer import write_options

    context = foxglove.Context()
    options = write_options(compression)
    writer = foxglove.open_mcap(out, context=context, writer_options=options)
    channels: dict[int, Any] = {}
    for schema, channel, _ in messages:
        if channel.id not in channels:
            kind = None
            if schema is not None:
                kind = foxglove.Schema(name=schema.name, encoding=schema.encoding, data=schema.data)
            channels[channel.id] = foxglove.Channel(
                channel.topic, message_encoding=channel.message_encoding, schema=kind,
                context=context,
            ).base  # fmt: skip
    return context, writer, channels


class ReplayRecorder:
    """A recorder writing a logged episode's messages again, through the SDK, in the episode.

    Made from the log of the same episode (read when made, before the episode is timed). Its
    steps take what a logger must take of each step: the episode loop calls the method's
    ``internals()`` and makes the step's record for any recorder, and :meth:`record` copies the
    step's joint and task-space values into rows, as :meth:`amex.log.batch.StepBatch.add` does.
    Every ``batch`` steps, as the logger writes its batches (:data:`amex.log.writer.BATCH`), it
    logs every message of the log stamped up to that step's time, already encoded, in the log's
    order; ``batch=1`` logs them as the steps come, each between the inner steps, where the
    SDK's calls run cold (on 2026-12-07 that cost 2-3 points of an episode more; the floors
    printed before that day were taken so). The SDK's context, file and channels are made at
    the first step, the header record with them; :meth:`finish` logs the rest, the other
    records, and closes.
    """

    def __init__(self, log: Path, out: Path, batch: int | None = None) -> None:
        from amex.log.writer import BATCH

        messages, self._records, self._compression = _read_log(log)
        order = sorted(range(len(messages)), key=lambda i: messages[i][2].log_time)  # stable
        self._messages = [messages[i] for i in order]
        self._times = [m.log_time for _, _, m in self._messages]
        self._data = [m.data for _, _, m in self._messages]
        self._logs: list[Any] = []  # per message, its channel's log (once the file is open)
        self._out = out
        self._next = 0
        self._open: tuple[Any, Any, dict[int, Any]] | None = None
        self._capacity = BATCH if batch is None else int(batch)
        if self._capacity < 1:
            raise ValueError(f"invalid batch={batch!r}; valid: an integer >= 1")
        self._row = 0
        self._rows: list[np.ndarray] | None = None

    def _start(self) -> None:
        """The SDK's context, file and channels, and the header record."""
        self._open = _open_again(self._out, self._messages, self._compression)
        channels = self._open[2]
        self._logs = [channels[channel.id].log for _, channel, _ in self._messages]
        for name, record in self._records[:1]:
            self._open[1].write_metadata(name, record)

    def _log_until(self, ns: int) -> None:
        logs, data, times, k, n = self._logs, self._data, self._times, self._next, len(self._logs)
        while k < n and times[k] <= ns:
            logs[k](data[k], times[k])
            k += 1
        self._next = k

    def record(self, step: Any) -> None:
        """Copy the step's values into a row; at a full batch, log its messages (class notes)."""
        if self._open is None:
            self._start()
        state, obs = step.state, step.observation
        values = (state.q, state.v, step.qacc, step.tau, obs.y, obs.yd, obs.goal[:3])
        if self._rows is None:
            self._rows = [np.zeros((self._capacity, len(v))) for v in values]
        i = self._row
        for rows, value in zip(self._rows, values, strict=True):
            rows[i] = value
        self._row = (i + 1) % self._capacity
        if not self._row:  # the batch is full: the logger writes it now
            self._log_until(round(step.t * 1e9))

    def finish(self, result: Any) -> None:
        """Log the rest of the messages, the other metadata records, and close the file."""
        if self._open is None:
            self._start()
        self._log_until(self._times[-1] if self._times else 0)
        assert self._open is not None
        context, writer, channels = self._open
        for name, values in self._records[1:]:
            writer.write_metadata(name, values)
        for base in channels.values():
            base.close()
        writer.close()


def _replayed(run: Any, env: int, log: Path, out: Path) -> tuple[float, float]:
    """Thread CPU and wall time of environment ``env`` recorded by a :class:`ReplayRecorder`."""
    from amex.experiment.runner import run_setup_with

    recorder = ReplayRecorder(log, out)  # reads the log: not timed
    return _timed(lambda: run_setup_with(run, env, recorder))


def _timed(run: object) -> tuple[float, float]:
    cpu, wall = time.thread_time_ns(), time.perf_counter_ns()
    run()  # type: ignore[operator]
    return (time.thread_time_ns() - cpu) * 1e-9, (time.perf_counter_ns() - wall) * 1e-9


def log_overhead(
    task: int = 3,
    method: str = "amex",
    envs: Sequence[int] = range(6),
    overrides: Sequence[str] = (),
    *,
    rounds: int = 1,
    verbose: bool = True,
) -> LogOverhead:
    """Thread CPU and wall time of ``envs``, each run plain and then logged (module notes).

    Args:
        task: the task, 0-4.
        method: the method's registry key.
        envs: the environments.
        overrides: further Hydra overrides (e.g. ``max_time=1``).
        rounds: how many times each environment is run each way (plain, logged, the SDK's
            floor, replayed, in turn); its times are the medians of its rounds. The same
            episode's thread CPU varies by up to ~20 % from one run to the next on a shared
            machine (2026-12-06: 106-134 ms for the DMP's Task 1, bimodal), more than a
            logger's changes: three rounds and more make the median steady.
        verbose: print one line per environment and the median overhead.
    """
    from amex.app.compose import load_config
    from amex.app.heap import settle
    from amex.experiment.runner import prepare, run_setup, setup

    if rounds < 1:
        raise ValueError(f"invalid rounds={rounds!r}; valid: an integer >= 1")
    config = load_config([f"task={task}", f"method={method}", *overrides])
    run = setup(config, prepare(config))
    rows: list[np.ndarray] = []
    with tempfile.TemporaryDirectory(prefix="amex-bench-log-") as tmp:
        first = next(iter(envs), 0)
        run_setup(run, first)  # warm-up, not counted
        run_setup(run, first, Path(tmp) / "warm.mcap")
        settle()  # the heap as amex-run's episodes see it (amex.app.heap; module notes)
        for env in envs:
            samples = []
            for _ in range(rounds):
                path = Path(tmp) / f"episode_{env:03d}.mcap"
                plain = _timed(lambda env=env: run_setup(run, env))
                logged = _timed(lambda env=env, path=path: run_setup(run, env, path))
                again = path.with_suffix(".again.mcap")
                floor = sdk_floor(path, again)
                again.unlink()
                replayed = _replayed(run, env, path, again)
                path.unlink()
                again.unlink()
                samples.append((plain[0], logged[0], plain[1], logged[1], floor, replayed[0]))
            row = np.median(np.array(samples), axis=0)
            rows.append(row)
            if verbose:
                print(
                    f"  env {env}: thread CPU plain {row[0]:.3f} s, logged {row[1]:.3f} s "
                    f"(+{(row[1] / row[0] - 1) * 100:.0f} %); wall plain {row[2]:.3f} s, "
                    f"logged {row[3]:.3f} s; the SDK alone {row[4]:.4f} s; replayed "
                    f"{row[5]:.3f} s" + (f" (medians of {rounds} rounds)" if rounds > 1 else "")
                )
    times = np.array(rows).reshape(-1, 6)
    result = LogOverhead(*times.T)
    if verbose:
        print(summary(task, method, result))
    return result


def summary(task: int, method: str, result: LogOverhead) -> str:
    """One line: the median and p95 overhead in thread CPU and wall time, and the plain median."""
    cpu, wall = result.overhead("thread") * 100, result.overhead("wall") * 100
    return (
        f"Task {task}, {method} ({len(cpu)} env): log=full overhead thread CPU median "
        f"+{np.median(cpu):.1f} % (p95 +{np.percentile(cpu, 95):.1f} %), wall median "
        f"+{np.median(wall):.1f} % (p95 +{np.percentile(wall, 95):.1f} %); plain episode "
        f"{np.median(result.plain_cpu) * 1e3:.0f} ms thread CPU; floor (the SDK writing the "
        f"same log alone) +{np.median(result.floor()) * 100:.1f} %; replayed (its messages "
        f"written a batch at a time, their values taken) +{np.median(result.replay()) * 100:.1f} %"
    )


def main(argv: list[str] | None = None) -> None:
    """Print the overhead of ``log=full`` for the given tasks and methods."""
    parser = OneLineParser(prog="amex-bench-log", description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, nargs="*", choices=range(5), default=[3])
    parser.add_argument("--methods", nargs="*", default=["amex"])
    parser.add_argument("--episodes", type=int, default=6, help="environments per task")
    parser.add_argument(
        "--rounds", type=int, default=3, help="runs of each environment each way (medians)"
    )
    parser.add_argument("--quiet", action="store_true", help="only the summary lines")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides, e.g. max_time=1")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes {args.episodes}: valid: an integer >= 1")
    if args.rounds < 1:
        parser.error(f"--rounds {args.rounds}: valid: an integer >= 1")
    lines = []
    for method in args.methods:
        for task in args.tasks:
            envs = range(args.episodes)
            result = log_overhead(
                task, method, envs, args.overrides, rounds=args.rounds, verbose=not args.quiet
            )
            lines.append(summary(task, method, result))
    if args.quiet:
        print("\n".join(lines))


if __name__ == "__main__":
    main()
