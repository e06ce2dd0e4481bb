"""Typed configuration of a run, and its validation.

These are plain dataclasses: the CLI registers them in Hydra's ConfigStore (only :mod:`amex.cli`
imports Hydra) and converts the composed config back into them, so library code and users'
scripts never need Hydra. Every physical field states its unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from amex.control.disturbance import DisturbanceConfig
from amex.control.osc import PD, OSCGains
from amex.episode import LoopConfig, MismatchConfig
from amex.errors import ConfigError
from amex.methods import METHODS, MethodConfig
from amex.perception import PerceptionConfig, PredictionConfig
from amex.plan.reference import PlanConfig
from amex.robot import PANDA_Q0, ROBOTS
from amex.scenario import TASKS, ScenarioConfig

LOG_LEVELS = ("none", "full")


@dataclass
class RobotConfig:
    """The arm and its start configuration.

    Attributes:
        name: robot model (only ``panda``).
        q0: start configuration, the Panda's neutral pose [rad].
    """

    name: str = "panda"
    q0: list[float] = field(default_factory=lambda: list(PANDA_Q0))


@dataclass
class ControllerConfig:
    """Inner-controller terms shared by all methods (the methods set their own pos/dir gains).

    Attributes:
        col: collision task gains (original: Kp 2500, Kd 100).
        joint: joint-target task gains, used by CR's joint commands (original: 100, 100).
        damping: joint damping task (original: Kd 10 at precision 0.1; we weight it 0.01).
        margin: collision margin (original 0.1 m), multiplied by ``scenario.scale`` [m].
        reg: regularizer H = reg * I of Eq. 4 [-].
        disturbance: compensation of unmodelled torques: ``none`` (the paper's controller),
            ``observer`` (generalized-momentum observer) or ``integral`` (integral action on the
            task errors); :mod:`amex.control.disturbance`.
        observer_bandwidth: the observer's gain K_O, bandwidth of its estimate [1/s].
        observer_limit: clamp of the observer's estimate, fraction of the torque limits [-].
        integral_gain: K_I of the integral action [1/s].
        integral_limit: bound of the integral's task acceleration [m/s^2, rad/s^2].
    """

    col: PD = field(default_factory=lambda: PD(2500.0, 100.0, 10.0))
    joint: PD = field(default_factory=lambda: PD(100.0, 100.0, 1.0))
    damping: PD = field(default_factory=lambda: PD(0.0, 10.0, 0.01))
    margin: float = 0.1
    reg: float = 1e-6
    disturbance: str = "none"
    observer_bandwidth: float = 20.0
    observer_limit: float = 1.0
    integral_gain: float = 10.0
    integral_limit: float = 50.0

    def compensation(self) -> DisturbanceConfig:
        """The inner controller's disturbance compensation (:mod:`amex.control.disturbance`)."""
        return DisturbanceConfig(
            kind=self.disturbance,
            bandwidth=float(self.observer_bandwidth),
            limit=float(self.observer_limit),
            integral_gain=float(self.integral_gain),
            integral_limit=float(self.integral_limit),
        )


@dataclass
class RunConfig:
    """One run: ``episodes`` environments of ``task`` executed with ``method``.

    Attributes:
        task: benchmark task, 0-4.
        method: the method and its parameters (Hydra group ``method``).
        episodes: number of environments (paper: 150).
        seed: seed of the scene sampling (>= 0).
        outer_hz: method update rate [Hz].
        inner_hz: controller and simulation rate [Hz], an integer multiple of ``outer_hz``.
        max_time: episode time limit [s].
        success_radius: final TCP-goal distance counted as success [m] (absolute, as the paper).
        stop_radius: the episode stops within this distance of the goal; the paper's 0.03 m on
            its 5x larger scene, multiplied by ``scenario.scale`` [m].
        log: ``none`` or ``full`` (one MCAP file per episode).
        perception: goal noise and latency (default exact).
        prediction: constant-velocity Kalman prediction of the goal (default off).
        mismatch: simulated arm versus the controller's model (default identical).
    """

    task: int = 0
    method: Any = field(default_factory=MethodConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    plan: PlanConfig = field(default_factory=PlanConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    prediction: PredictionConfig = field(default_factory=PredictionConfig)
    mismatch: MismatchConfig = field(default_factory=MismatchConfig)
    episodes: int = 150
    seed: int = 0
    outer_hz: float = 100.0
    inner_hz: float = 1000.0
    max_time: float = 10.0
    success_radius: float = 0.03
    stop_radius: float = 0.03
    log: str = "none"

    @property
    def loop(self) -> LoopConfig:
        """The episode loop's settings."""
        return LoopConfig(
            outer_hz=float(self.outer_hz),
            inner_hz=float(self.inner_hz),
            max_time=float(self.max_time),
            success_radius=float(self.success_radius),
            stop_radius=float(self.stop_radius) * float(self.scenario.scale),
        )

    def gains(self) -> OSCGains:
        """Inner-controller gains: the method's task gains plus the shared terms."""
        c = self.controller
        return OSCGains(
            pos=self.method.pos,
            dir=self.method.dir,
            col=c.col,
            joint=c.joint,
            damping=c.damping,
            margin=c.margin * self.scenario.scale,
            reg=c.reg,
        )


def validate(config: RunConfig) -> None:
    """Raise :class:`ConfigError` naming the first invalid value and the valid choices."""
    if isinstance(config.task, bool) or config.task not in TASKS:
        raise ConfigError.invalid("task", config.task, TASKS)
    name = getattr(config.method, "name", None)
    if name not in METHODS:
        raise ConfigError.invalid("method", name, sorted(METHODS))
    if config.episodes < 1:
        raise ConfigError.invalid("episodes", config.episodes, "an integer >= 1")
    if config.seed < 0:
        raise ConfigError.invalid("seed", config.seed, "an integer >= 0")
    if config.log not in LOG_LEVELS:
        raise ConfigError.invalid("log", config.log, LOG_LEVELS)
    if config.robot.name not in ROBOTS:
        raise ConfigError.invalid("robot", config.robot.name, ROBOTS)
    config.scenario.validate()
    config.loop.validate()
    config.perception.validate()
    config.prediction.validate()
    config.mismatch.validate()
    config.controller.compensation().validate()
    plan = config.plan
    if not (plan.dt > 0 and plan.duration > 0):
        raise ConfigError.invalid("plan.dt", plan.dt, "dt > 0 and duration > 0 [s]")
    if not math.isclose(plan.duration / plan.dt, round(plan.duration / plan.dt), abs_tol=1e-9):
        raise ConfigError.invalid("plan.duration", plan.duration, "an integer multiple of plan.dt")
    if plan.max_iterations < 1:
        raise ConfigError.invalid("plan.max_iterations", plan.max_iterations, "an integer >= 1")
    for key in ("pos", "dir"):
        gains = getattr(config.method, key)
        if gains.kp < 0 or gains.kd < 0 or gains.weight < 0:
            raise ConfigError.invalid(f"method.{key}", gains, "kp, kd, weight >= 0")
