"""The live session: one episode at a time in its own thread, driven by the page's commands.

:class:`LiveSession` composes the configuration once per method (``amex-run``'s composition with
``method=<name>``; overrides of ``method.*`` apply to the method they were given for), loads the
robot and the reference plan once, and runs episodes with :func:`amex.sim.episode.run_episode`
on a :class:`~amex.sim.live.LiveScenario` and a :class:`~amex.sim.pacing.LiveRecorder`. The live
loop differs from a benchmark episode in two stopping rules only: it does not stop at the goal
(move it again and the method follows) and its time limit is the session's (``max_time``, 5 min
by default). Everything else (rates, controller, perception, prediction, mismatch, disturbance
compensation) is the configuration's.

Commands (any thread): :meth:`switch_method`, :meth:`reset` (``"restart"``: the scene as it is,
from the start pose; ``"next"``: the task's next environment; ``"reference"``: the reference
scene, Task 0), :meth:`pause`, :meth:`resume`, :meth:`step`, :meth:`set_speed`, :meth:`set_goal`,
:meth:`set_obstacle`, :meth:`start_recording`, :meth:`stop_recording`, :meth:`close`. A command
that changes the episode stops the running one at its next outer step and the thread starts the
next. The page reads :attr:`state` (a :class:`LiveState`, replaced at every outer step).

Over 400 lines on purpose: one class, the live session's state (method switches, pause and single
steps, goal edits, the logged episode), whose handlers share one lock and its state; split, that
lock discipline would spread over modules.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from amex.core.errors import AmexError
from amex.experiment.runner import EpisodeSetup, RunContext, preflight, prepare, setup
from amex.methods import METHODS
from amex.sim.episode import StepRecord, run_episode
from amex.sim.live import LiveScenario, PlanView, TimedMethod, method_plan
from amex.sim.pacing import EpisodeStopped, LiveRecorder, PaceStats
from amex.sim.scenario import Scenario, make_scenario

SCENES = ("restart", "next", "reference")
PHASE_KEYS = (("s", "phase s"), ("phase", "phase x"), ("index", "reference index"))
PLAN_EVERY = 0.2  # [s] wall time between two readings of the method's plan
PATH_EVERY = 2  # outer steps between two points of the executed path
PATH_POINTS = 3000  # points of the executed path kept
HISTORY_SECONDS = 10.0  # [s] of simulation shown in the live plot


@dataclass(frozen=True)
class LiveState:
    """What the page shows, as of the last outer step.

    Attributes:
        episode: counts the episodes of the session (a new one clears the paths).
        method: the method's name.
        task, env: the scene (task 0 for the reference scene).
        t: simulation time [s].
        q: joint angles, shape (n,) [rad].
        tcp: TCP position, shape (3,) [m].
        goal: the true goal, shape (3,) [m].
        goal_seen: the goal the method was given (perception applied), shape (3,) [m].
        obstacles: obstacle centres (k, 3) [m]; radii (k,) [m].
        distance: TCP to the true goal [m].
        phase_name, phase: the method's phase (AMEX s, DMP x, Track's index), or "" and NaN.
        step_time: the method's last step [s].
        pace: the loop's pacing (:class:`~amex.sim.pacing.PaceStats`).
        status: a sentence: running, paused, ended (why), failed (why).
        recording: the log being written, or "".
    """

    episode: int = 0
    method: str = ""
    task: int = 0
    env: int = 0
    t: float = 0.0
    q: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tcp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    goal: np.ndarray = field(default_factory=lambda: np.zeros(3))
    goal_seen: np.ndarray = field(default_factory=lambda: np.zeros(3))
    obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    distance: float = math.nan
    phase_name: str = ""
    phase: float = math.nan
    step_time: float = math.nan
    pace: PaceStats = PaceStats(math.nan, 0.0, 0, True)
    status: str = "starting"
    recording: str = ""


@dataclass
class _Request:
    """What the next episode should be."""

    method: str
    scene: str = "restart"
    record: bool = False


class LiveSession:
    """Runs live episodes (module notes).

    Args:
        overrides: the command line's overrides, as for ``amex-run``.
        max_time: time limit of a live episode [s].
        speed: simulated seconds per wall second.
        record_dir: where recordings are written.
        paused: start paused.
    """

    def __init__(
        self,
        overrides: list[str],
        max_time: float = 300.0,
        speed: float = 1.0,
        record_dir: Path = Path("runs/live"),
        paused: bool = False,
    ) -> None:
        from amex.app.compose import load_config

        self._load_config = load_config
        self.overrides = list(overrides)
        self.max_time = float(max_time)
        self.record_dir = Path(record_dir)
        self._configs: dict[str, Any] = {}
        config = self.config_for(None)
        preflight(config)
        self.method_names = sorted(METHODS)
        self.context: RunContext = prepare(config)
        self.task, self.seed = int(config.task), int(config.seed)
        self._setups: dict[str, EpisodeSetup] = {}
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._request: _Request | None = _Request(config.method.name, "restart")
        self._speed = float(speed)
        self._paused = bool(paused)
        self._closed = False
        self._recorder: LiveRecorder | None = None
        self._scenario: LiveScenario | None = None
        self._scene = self._setup(config.method.name).scene  # the same for every method
        self._base: Scenario = self._make_scene(self.task, 0)
        self._method: TimedMethod | None = None
        self.state = LiveState(method=config.method.name, task=self.task)
        self.plan: PlanView = PlanView()
        self.path: deque[np.ndarray] = deque(maxlen=PATH_POINTS)
        self.history: deque[tuple[float, float, float]] = deque()
        self.last_log: Path | None = None
        self._episode = 0
        self._plan_time = 0.0
        self._thread = threading.Thread(target=self._run, name="amex-live-episodes", daemon=True)

    # -- configuration ----------------------------------------------------------------------
    def config_for(self, method: str | None) -> Any:
        """The run configuration with ``method`` (None: the command line's own)."""
        key = method or ""
        if key not in self._configs:
            overrides = self.overrides
            if method is not None:
                given = [o.split("=", 1)[1] for o in overrides if o.startswith("method=")]
                if not given or given[-1] != method:  # method.* overrides were for another one
                    overrides = [o for o in overrides if not o.lstrip("+~").startswith("method")]
                    overrides = [*overrides, f"method={method}"]
            self._configs[key] = self._load_config(overrides)
        return self._configs[key]

    def _setup(self, method: str) -> EpisodeSetup:
        if method not in self._setups:
            config = self.config_for(method)
            base = setup(config, self.context)
            # never stop at the goal: a distance is >= 0 (LoopConfig.validate would refuse -1, the
            # loop only compares with it)
            loop = dataclasses.replace(base.loop, max_time=self.max_time, stop_radius=-1.0)
            self._setups[method] = dataclasses.replace(base, loop=loop)
        return self._setups[method]

    def _make_scene(self, task: int, env: int) -> Scenario:
        plan = self.context.plan
        return make_scenario(self._scene, task, self.seed, env, plan.y[0, :3], plan.duration)

    # -- commands ---------------------------------------------------------------------------
    def start(self) -> None:
        """Start the episode thread."""
        self._thread.start()

    def close(self) -> None:
        """Stop the running episode and the thread (a recording is finished)."""
        with self._wake:
            self._closed = True
            self._wake.notify_all()
        self._stop_episode()
        if self._thread.is_alive():
            self._thread.join(timeout=10)

    def switch_method(self, name: str) -> None:
        """Run ``name`` from the start pose in the scene as it is."""
        if name not in METHODS:
            raise AmexError(f"invalid method={name!r}; valid: {', '.join(sorted(METHODS))}")
        self._setup(name)  # compose now: a bad configuration fails here, not in the thread
        self._new_request(_Request(name, "restart"))

    def reset(self, scene: str = "restart") -> None:
        """Start again: ``restart``, ``next`` environment or the ``reference`` scene."""
        if scene not in SCENES:
            raise AmexError(f"invalid scene={scene!r}; valid: {', '.join(SCENES)}")
        self._new_request(_Request(self.state.method, scene))

    def start_recording(self) -> None:
        """Restart the scene as it is and write that episode as an MCAP log."""
        self._new_request(_Request(self.state.method, "restart", record=True))

    def stop_recording(self) -> None:
        """End the recorded episode (the log is finished); the scene restarts unrecorded."""
        self._new_request(_Request(self.state.method, "restart"))

    def pause(self) -> None:
        """Hold the simulation at its next outer step.

        The status reads ``paused`` once the loop has come to rest (the recorder's ``on_hold``),
        not when asked: a step under way finishes first, and the state shown is that step's.
        """
        self._paused = True
        if self._recorder is not None:
            self._recorder.pause()

    def resume(self) -> None:
        """Run on in real time."""
        self._paused = False
        if self._recorder is not None:
            self._recorder.resume()
            self._status("running")

    @property
    def paused(self) -> bool:
        """Whether the simulation is held."""
        return self._paused

    def step(self) -> None:
        """While paused: one outer step."""
        if self._recorder is not None:
            self._recorder.step()

    def set_speed(self, speed: float) -> None:
        """Simulated seconds per wall second."""
        self._speed = float(speed)
        if self._recorder is not None:
            self._recorder.set_speed(speed)

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second."""
        return self._speed

    def set_goal(self, position: Any) -> None:
        """Move the goal to ``position`` (3,) [m], now."""
        if self._scenario is not None:
            self._scenario.set_goal(position)

    def set_obstacle(self, k: int, position: Any) -> None:
        """Move obstacle ``k`` to ``position`` (3,) [m], now."""
        if self._scenario is not None and 0 <= k < self._scenario.n_obstacles:
            self._scenario.set_obstacle(k, position)

    @property
    def scenario(self) -> LiveScenario | None:
        """The running episode's scene."""
        return self._scenario

    def goal_now(self) -> np.ndarray:
        """The true goal at the current simulation time, shape (3,) [m]."""
        s = self._scenario
        return np.zeros(3) if s is None else np.array(s.goal_at(s.now))

    def _new_request(self, request: _Request) -> None:
        with self._wake:
            self._request = request
            self._wake.notify_all()
        self._stop_episode()

    def _stop_episode(self) -> None:
        recorder = self._recorder
        if recorder is not None:
            recorder.stop()

    # -- the episode thread -----------------------------------------------------------------
    def _run(self) -> None:
        while True:
            with self._wake:
                while self._request is None and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                request, self._request = self._request, None
            assert request is not None
            try:
                self._episode_of(request)
            except AmexError as e:  # a method or a log that cannot be built: say so, wait
                self._status(f"error: {e}")
            except Exception as e:  # a plugin's own failure: the session goes on
                self._status(f"error: {type(e).__name__}: {e}"[:300])

    def _scene_for(self, request: _Request) -> Scenario:
        if request.scene == "next":
            env = self._base.env + 1 if self._base.task == self.task else 0
            self._base = self._make_scene(self.task, env)
        elif request.scene == "reference":
            self._base = self._make_scene(0, 0)
        elif self._scenario is not None:
            self._base = self._scenario.snapshot()  # as it is now: hand-moved objects stay
        return self._base

    def _episode_of(self, request: _Request) -> None:
        s = self._setup(request.method)
        context = self.context
        base = self._scene_for(request)
        scenario = LiveScenario(base)
        method = TimedMethod(s.method.from_plan(context.plan, s.params, s.outer_dt, context.robot))
        logger = self._logger(request, s, base) if request.record else None
        recorder = LiveRecorder(scenario, self._speed, self._on_step, logger, self._paused,
                                 on_hold=self._on_hold)  # fmt: skip
        self._episode += 1
        self.path.clear()
        self.history.clear()
        self.plan = PlanView()
        self._scenario, self._method, self._recorder = scenario, method, recorder
        self.state = dataclasses.replace(
            self.state, episode=self._episode, method=request.method, task=base.task,
            env=base.env, t=0.0, status="starting", recording=str(logger.path) if logger else "",
            radii=np.array(base.obstacle_radii),
        )  # fmt: skip
        robot, world = context.robot, s.world
        status = ""
        try:
            scene = cast(Scenario, scenario)  # duck-typed: amex.sim.live's notes
            result = run_episode(robot, method, scene, s.gains, s.loop, recorder, **world)
            status = "ended: " + (
                result.failure
                or (
                    "the method finished"
                    if method.finished
                    else f"time limit {s.loop.max_time:g} s"
                )
            )
            if logger is not None:
                logger.close()
        except EpisodeStopped:
            status = "stopped"
            if logger is not None:
                logger.close({"status": "stopped", "reason": "stopped on the live page"})
        except BaseException:
            if logger is not None:
                logger.close({"status": "error", "error": "the live session failed"})
            raise
        finally:
            self._recorder = None
        if logger is not None:
            self.last_log = logger.path
        self._status(status)

    def _logger(self, request: _Request, s: EpisodeSetup, base: Scenario) -> Any:
        from amex.log import EpisodeLogger

        stamp = time.strftime("%Y%m%d-%H%M%S")
        name = f"{stamp}_task{base.task}_env{base.env}_{request.method}.mcap"
        metadata = {
            "task": base.task, "method": request.method, "env": base.env, "seed": base.seed,
            "live": True, "overrides": self.overrides,
        }  # fmt: skip
        return EpisodeLogger(self.record_dir / name, self.context.robot, self.context.plan,
                             base, metadata)  # fmt: skip

    def _status(self, status: str) -> None:
        self.state = dataclasses.replace(self.state, status=status)

    def _on_hold(self) -> None:
        """The recorder's hold (in the loop's thread): the scene stands still from here."""
        self._status("paused")

    def _on_step(self, step: StepRecord, pace: PaceStats) -> None:
        """The recorder's observer: the state for the page (in the loop's thread)."""
        scenario, method = self._scenario, self._method
        assert scenario is not None and method is not None
        obs, t = step.observation, step.t
        tcp = np.array(obs.y[:3])
        goal = np.array(scenario.goal_at(t))
        distance = float(np.linalg.norm(tcp - goal))
        internals = step.internals
        phase_name, phase = "", math.nan
        for key, label in PHASE_KEYS:
            value = internals.get(key)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                phase_name, phase = label, float(value)
                break
        now = time.perf_counter()
        if now >= self._plan_time:
            self._plan_time = now + PLAN_EVERY
            self.plan = method_plan(method, internals)
        k = int(round(t / self._setups[self.state.method].outer_dt))
        if k % PATH_EVERY == 0:
            self.path.append(tcp)
            self.history.append((t, distance, phase))
            while self.history and self.history[0][0] < t - HISTORY_SECONDS:
                self.history.popleft()
        recorder = self._recorder
        paused = recorder is not None and recorder.paused
        self.state = dataclasses.replace(
            self.state, t=t, q=np.array(obs.q), tcp=tcp, goal=goal,
            goal_seen=np.array(obs.goal[:3]), obstacles=np.array(obs.obstacles),
            distance=distance, phase_name=phase_name, phase=phase, step_time=method.last_step,
            pace=pace,
            status="paused" if paused else "running",
        )  # fmt: skip
