"""The recorder of a live episode: the two-rate loop paced to the wall clock.

:class:`LiveRecorder` is the recorder of ``amex-live``'s :func:`amex.sim.episode.run_episode`. Its
``record()``, called once per outer step, hands the step to an observer (the page), forwards it to
an optional inner recorder (an MCAP :class:`~amex.log.writer.EpisodeLogger`), and then waits until
the wall clock has caught up with the simulation time divided by the speed factor; while paused
it blocks (:meth:`LiveRecorder.step` lets one outer step through), and after
:meth:`LiveRecorder.stop` it raises :class:`EpisodeStopped`, which ends the episode
(``run_episode`` lets it pass: it is no :class:`~amex.core.errors.AmexError`).

Real time: if the loop falls behind the wall clock by more than :data:`MAX_LAG`, the clock is
reset to it (no catching up in a burst) and the step counts as late; :class:`PaceStats` reports
the real-time factor (simulated over wall seconds, pauses excluded) and the loop's load (its own
compute time over the wall time it may take).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from amex.sim.episode import Recorder, StepRecord
from amex.sim.metrics import EpisodeResult

if TYPE_CHECKING:
    from amex.sim.live import LiveScenario

MAX_LAG = 0.05  # [s] behind the wall clock by more than this: re-synchronize, count as late


class EpisodeStopped(Exception):  # noqa: N818 (a stop, not an error)
    """Raised by :meth:`LiveRecorder.record` to end the episode (reset, method switch, quit)."""


@dataclass(frozen=True)
class PaceStats:
    """How the loop keeps pace with the wall clock.

    Attributes:
        realtime_factor: simulated seconds per wall second over the last second, pauses excluded
            (the speed factor when the loop keeps pace) [-].
        load: the loop's own compute time over the wall time an outer step may take (< 1: it
            keeps pace; the rest of the period it sleeps) [-].
        late_steps: outer steps that found the loop more than :data:`MAX_LAG` behind.
        keeps_pace: the realtime factor is within 10 % of the speed factor (or paused).
    """

    realtime_factor: float
    load: float
    late_steps: int
    keeps_pace: bool


class LiveRecorder:
    """The recorder of a live episode: pacing, pause, single steps, stop (module notes).

    Args:
        scenario: the live scene (its :attr:`LiveScenario.now` is kept current).
        speed: simulated seconds per wall second (1: real time).
        on_step: called with each outer step and the pacing statistics, in the loop's thread
            (keep it short).
        inner: a recorder the steps are forwarded to (an MCAP logger), or None.
        paused: start paused.
        on_hold: called in the loop's thread when the loop comes to rest in a pause, after the
            last step's ``on_step``: from then on the scene stands still until a resume or step.
    """

    def __init__(
        self,
        scenario: LiveScenario,
        speed: float = 1.0,
        on_step: Callable[[StepRecord, PaceStats], None] | None = None,
        inner: Recorder | None = None,
        paused: bool = False,
        on_hold: Callable[[], None] | None = None,
    ) -> None:
        self.scenario = scenario
        self.on_step = on_step
        self.on_hold = on_hold
        self.inner = inner
        self.result: EpisodeResult | None = None
        self._speed = _checked_speed(speed)
        self._cond = threading.Condition()
        self._paused = paused
        self._steps_allowed = 0
        self._stopped = False
        self._held = False  # the loop rests in a pause
        self._base: float | None = None  # wall time of simulation time 0 at the current pace
        self._resumed = time.perf_counter()  # when record() last returned
        self._window: deque[tuple[float, float]] = deque()  # (wall, sim) while running
        self._load = 0.0
        self._late = 0
        self._stats = PaceStats(math.nan, 0.0, 0, True)

    # -- controls (any thread) -------------------------------------------------------------
    @property
    def paused(self) -> bool:
        """Whether the loop waits for :meth:`resume` or :meth:`step`."""
        return self._paused

    @property
    def held(self) -> bool:
        """Whether the loop has come to rest in a pause (no step is under way)."""
        return self._held

    @property
    def speed(self) -> float:
        """Simulated seconds per wall second."""
        return self._speed

    @property
    def stats(self) -> PaceStats:
        """The latest pacing statistics."""
        return self._stats

    def set_speed(self, speed: float) -> None:
        """Change the speed factor (from the next step on)."""
        with self._cond:
            self._speed = _checked_speed(speed)
            self._base = None
            self._window.clear()
            self._cond.notify_all()

    def pause(self) -> None:
        """Hold the loop at its next outer step."""
        with self._cond:
            self._paused = True
            self._cond.notify_all()

    def resume(self) -> None:
        """Run on in real time."""
        with self._cond:
            self._paused = False
            self._held = False
            self._base = None
            self._window.clear()
            self._cond.notify_all()

    def step(self, n: int = 1) -> None:
        """While paused: let ``n`` more outer steps through."""
        with self._cond:
            self._steps_allowed += n
            self._cond.notify_all()

    def stop(self) -> None:
        """End the episode at its next outer step (:class:`EpisodeStopped`)."""
        with self._cond:
            self._stopped = True
            self._cond.notify_all()

    # -- Recorder ---------------------------------------------------------------------------
    def record(self, step: StepRecord) -> None:
        """One outer step: observe, forward, then wait for the wall clock (module notes)."""
        now = time.perf_counter()
        busy = now - self._resumed
        self.scenario.now = step.t
        if self.inner is not None:
            self.inner.record(step)
        self._update_stats(step.t, now, busy)
        if self.on_step is not None:
            self.on_step(step, self._stats)
        self._wait(step.t)
        self._resumed = time.perf_counter()

    def finish(self, result: EpisodeResult) -> None:
        """The episode's end: keep the result, forward it."""
        self.result = result
        if self.inner is not None:
            self.inner.finish(result)

    # -- pacing -----------------------------------------------------------------------------
    def _update_stats(self, t: float, now: float, busy: float) -> None:
        period = max(t - self._window[-1][1], 1e-9) / self._speed if self._window else None
        if period is not None and not self._paused:
            self._load += 0.1 * (min(busy / period, 100.0) - self._load)
        window = self._window
        if not self._paused:
            window.append((now, t))
            while len(window) > 2 and now - window[0][0] > 1.0:
                window.popleft()
        factor = math.nan
        if len(window) >= 2 and window[-1][0] - window[0][0] > 0.2:
            factor = (window[-1][1] - window[0][1]) / (window[-1][0] - window[0][0])
        keeps = self._paused or not math.isfinite(factor) or factor >= 0.9 * self._speed
        self._stats = PaceStats(factor, self._load, self._late, keeps)

    def _wait(self, t: float) -> None:
        with self._cond:
            while True:
                if self._stopped:
                    self._held = False
                    raise EpisodeStopped()
                if self._paused:
                    if self._steps_allowed > 0:
                        self._steps_allowed -= 1
                        self._base = None
                        self._window.clear()
                        self._held = False
                        return
                    if not self._held:
                        self._held = True
                        if self.on_hold is not None:
                            self.on_hold()
                    self._cond.wait(0.1)
                    continue
                now = time.perf_counter()
                if self._base is None:
                    self._base = now - t / self._speed
                remaining = self._base + t / self._speed - now
                if remaining <= 0.0:
                    if remaining < -MAX_LAG:  # behind: carry on from here, no burst
                        self._late += 1
                        self._base = now - t / self._speed
                    return
                self._cond.wait(remaining)


def _checked_speed(speed: float) -> float:
    speed = float(speed)
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"invalid speed={speed!r}; valid: a factor > 0")
    return speed
