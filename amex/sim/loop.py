"""What the episode loop is configured with and what it reports while it runs.

:class:`LoopConfig` (rates and stopping rules), :class:`StepRecord` and the :class:`Recorder` it
is given (the MCAP logger, the live view), and :class:`Trace`, what the loop collects for the
episode's metrics (:mod:`amex.sim.metrics`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np

from amex.core.errors import ConfigError
from amex.core.schema import check_tree
from amex.core.types import Command

if TYPE_CHECKING:
    from amex.control.collision import CollisionModel
    from amex.control.state import RobotState
    from amex.methods.base import Observation
    from amex.sim.metrics import EpisodeResult


#: What an episode's ``final_time`` counts (:attr:`LoopConfig.final_time`).
FINAL_TIMES = ("elapsed", "samples")


def authors_samples(
    k: int, time_limit: bool, ended_by_method: bool, max_time: float, dt: float
) -> int:
    """The joint samples the authors' harness wrote for an episode that ended at our step ``k``.

    Their loop wrote the start and then one sample per inner step, and their evaluation
    (``evalRun.m``) took ``samples x 1 ms`` as the final time. They checked the stop rule
    before each inner step as we do, so an episode that reached its goal at our step k wrote
    k + 1 samples; one that their CR ended (fewer than 2 knots left) ran one more inner step
    after the end was set, k + 2; and one that ran out of time stopped once ``t``, summed step
    by step in floating point (``t += dt``), reached ``max_time``: at 1 ms, 10001 steps for 10 s.
    """
    if time_limit:
        t, steps = 0.0, 0
        while t < max_time:
            t += dt
            steps += 1
        return steps + 1
    return k + 2 if ended_by_method else k + 1


@dataclass(frozen=True)
class LoopConfig:
    """Rates and stopping rules of the episode loop.

    Attributes:
        outer_hz: method update rate [Hz] (paper: 100).
        inner_hz: controller and simulation rate [Hz] (paper: 1000); an integer multiple of
            ``outer_hz``.
        max_time: episode time limit [s] (original: 10).
        success_radius: final TCP-goal distance that counts as success [m] (paper: 0.03).
        stop_radius: TCP-goal distance at which the episode stops [m].
        speed_limit_factor: the simulation counts as diverged when a joint moves faster than this
            many times its rated speed [-].
        kinematic: integrate the controller's accelerations instead of simulating the dynamics
            (module notes).
        state_lag: methods see the task state (y, y_dot) of the previous inner step, and the
            stop rule its TCP, as in the authors' harness (module notes); joint states are
            current either way.
        final_time: what ``final_time`` reports: ``elapsed``, the time of the last step (ours),
            or ``samples``, the authors' count: the joint samples their harness wrote times
            the inner period (:func:`authors_samples`).
    """

    outer_hz: float = 100.0
    inner_hz: float = 1000.0
    max_time: float = 10.0
    success_radius: float = 0.03
    stop_radius: float = 0.006
    speed_limit_factor: float = 5.0
    kinematic: bool = False
    state_lag: bool = False
    final_time: str = "elapsed"

    @property
    def substeps(self) -> int:
        """Inner steps per outer step."""
        return int(round(self.inner_hz / self.outer_hz))

    def validate(self) -> None:
        """Raise :class:`ConfigError` on rates or limits the loop cannot run with."""
        check_tree(self)  # finite, >= 0
        if not self.outer_hz > 0:
            raise ConfigError.invalid("outer_hz", self.outer_hz, "a rate > 0 [Hz]")
        if not self.inner_hz > 0:
            raise ConfigError.invalid("inner_hz", self.inner_hz, "a rate > 0 [Hz]")
        ratio = self.inner_hz / self.outer_hz
        if ratio < 1 or abs(ratio - round(ratio)) > 1e-9:
            multiples = ", ".join(f"{self.outer_hz * k:g}" for k in (1, 2, 5, 10, 20))
            raise ConfigError(
                f"invalid inner_hz={self.inner_hz:g} with outer_hz={self.outer_hz:g}; "
                f"inner_hz must be an integer multiple of outer_hz, e.g. {multiples}"
            )
        if not self.max_time > 0:
            raise ConfigError.invalid("max_time", self.max_time, "a duration > 0 [s]")
        if not self.success_radius > 0:
            raise ConfigError.invalid("success_radius", self.success_radius, "a distance > 0 [m]")
        if not self.stop_radius > 0:
            raise ConfigError.invalid("stop_radius", self.stop_radius, "a distance > 0 [m]")
        if self.final_time not in FINAL_TIMES:
            raise ConfigError.invalid("final_time", self.final_time, FINAL_TIMES)


class StepRecord(NamedTuple):
    """What a recorder sees at each outer step (after the method's step).

    A named tuple, made at every outer step of a recorded episode: a third of a frozen
    dataclass's cost (0.6 against 1.9 us, 2026-12-07).
    """

    t: float
    state: RobotState
    observation: Observation
    command: Command
    internals: dict[str, Any]
    tau: np.ndarray
    qacc: np.ndarray


class Recorder(Protocol):
    """Receives the outer steps of an episode (e.g. the MCAP logger)."""

    def record(self, step: StepRecord) -> None:
        """Called once per outer step."""

    def finish(self, result: EpisodeResult) -> None:
        """Called once when the episode ends, with its result."""


class Trace:
    """What an episode's metrics need beyond the loop's own state (filled while it runs).

    Attributes:
        compute_times: wall time of each outer step of the method [s].
        cpu_times: thread CPU time of each outer step of the method [s].
        tcp: TCP position at every outer step [m].
        clearance: smallest arm-obstacle distance at the outer steps so far [m].
        path_length: length of the TCP path so far, from every inner step [m].
        axis: the TCP z-axis at the last step.
    """

    def __init__(self) -> None:
        self.compute_times: list[float] = []
        self.cpu_times: list[float] = []
        self.tcp: list[list[float]] = []
        self.clearance = math.inf
        self.path_length = 0.0
        self.axis: list[float] = [math.nan] * 3

    def outer(self, state: RobotState, collision: CollisionModel | None, data: Any) -> None:
        """Sample the outer step: its TCP, and its arm-obstacle clearance."""
        self.tcp.append(state.y_list[:3])
        self.axis = state.y_list[3:6]
        if collision is not None:
            self.clearance = min(self.clearance, collision.min_distance(data, state))
