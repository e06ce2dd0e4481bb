"""Typed configuration of a run, and its validation.

These are plain dataclasses: the CLI registers them in Hydra's ConfigStore (only :mod:`amex.app.cli`
imports Hydra) and converts the composed config back into them, so library code and users'
scripts never need Hydra. Every physical field states its unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from amex.control.disturbance import DisturbanceConfig
from amex.control.osc import ControllerGains, OSCGains
from amex.core.errors import ConfigError
from amex.core.scaling import scale_power, scale_value, scaled, to_scene_units
from amex.core.schema import check_tree, limits
from amex.experiment.shards import ShardSpec, shard_envs
from amex.methods import IMPLEMENTATIONS, METHODS, MethodConfig
from amex.plan.reference import PlanConfig
from amex.robot import RobotConfig, load_robot
from amex.robot.geometry import METRICS
from amex.sim.loop import LoopConfig
from amex.sim.perception import PerceptionConfig, PredictionConfig
from amex.sim.scenario import TASKS, ScenarioConfig
from amex.sim.simulation import MismatchConfig

LOG_LEVELS = ("none", "full")
#: How ``log=full`` compresses its chunks: the keys of :data:`amex.log.writer.COMPRESSIONS`, its
#: default first (named here so that a configuration is checked without importing the SDK).
LOG_COMPRESSIONS = ("lz4", "zstd", "none")
MAX_PLAN_STEPS = 100_000  # reference-plan knots; beyond, the solver's matrices exhaust memory
#: Episodes of one run: more is days of CPU and its bookkeeping would not fit in memory; a larger
#: study splits over seeds or shards.
MAX_EPISODES = 1_000_000
#: Inner steps of one episode (max_time x inner_hz): each keeps its joint angles for the paper's
#: metric (2e6 steps of a 7-joint arm: 112 MB).
MAX_EPISODE_STEPS = 2_000_000
SIMULATIONS = ("dynamic", "kinematic")


@dataclass
class ControllerConfig(ControllerGains):
    """Inner-controller terms shared by all methods (the methods set their own pos/dir gains).

    The gains are :class:`~amex.control.osc.ControllerGains`' (declared there once); the run's
    configuration states the margin in original units and adds the disturbance compensation.

    Attributes:
        margin: collision margin (original 0.1 m; scene units, :mod:`amex.core.scaling`) [m].
        proxy_arm_radii: with ``collision_cost=proxy``, the radius of each arm capsule in the
            authors' proxy cost (their swift mesh radii: 0.3 m for a link of the chain, 2e-4 m
            for its TCP; a length in original units); empty: each capsule's bounding radius
            (half length + radius), which on the chain are theirs [m].
        proxy_obstacle_radius: the obstacles' radius in the proxy cost (theirs 0.1 m; original
            units) [m].
        disturbance: compensation of unmodelled torques: ``none`` (the paper's controller),
            ``observer`` (generalized-momentum observer) or ``integral`` (integral action on the
            task errors); :mod:`amex.control.disturbance`. Dynamic simulation only.
        observer_bandwidth: the observer's gain K_O, bandwidth of its estimate [1/s].
        observer_limit: clamp of the observer's estimate, fraction of the torque limits [-].
        integral_gain: K_I of the integral action [1/s].
        integral_limit: bound of the integral's task acceleration [m/s^2, rad/s^2].
    """

    # in original units here (the controller takes scene units): redeclared with its scale power
    margin: float = field(default=0.1, metadata=scaled(1))
    proxy_arm_radii: list[float] = field(default_factory=list, metadata=scaled(1))
    proxy_obstacle_radius: float = field(default=0.1, metadata={**scaled(1), **limits(gt=0)})
    disturbance: str = "none"
    observer_bandwidth: float = field(default=20.0, metadata=limits(gt=0))
    observer_limit: float = field(default=1.0, metadata=limits(gt=0, le=1))
    integral_gain: float = field(default=10.0, metadata=limits(gt=0))
    integral_limit: float = field(default=50.0, metadata=limits(gt=0))

    def compensation(self) -> DisturbanceConfig:
        """The inner controller's disturbance compensation (:mod:`amex.control.disturbance`)."""
        return DisturbanceConfig(
            kind=self.disturbance,
            bandwidth=float(self.observer_bandwidth),
            limit=float(self.observer_limit),
            integral_gain=float(self.integral_gain),
            integral_limit=float(self.integral_limit),
        )

    def validate(self) -> None:
        """Raise :class:`ConfigError` for an unknown ``disturbance`` or ``collision_cost``."""
        super().validate()
        self.compensation().validate()


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
        stop_radius: the episode stops within this distance of the goal; the paper's 0.03 m
            (scene units, :mod:`amex.core.scaling`) [m].
        sim: ``dynamic`` (MuJoCo integrates the torques of the inner controller) or
            ``kinematic`` (the controller's joint accelerations are integrated directly, as the
            authors' code did; :mod:`amex.sim.episode`).
        state_lag: methods and the stop rule see the task state one inner step late, as in the
            authors' loop (:mod:`amex.sim.episode`).
        final_time: ``elapsed`` (the time of the episode's last step) or ``samples`` (the
            authors' count: their joint samples times 1 ms, 1-2 ms more;
            :func:`amex.sim.loop.authors_samples`).
        std_ddof: the delta degrees of freedom of every standard deviation the run's summary and
            the tables report (``2 std``): 0, the population's (ours), or 1, MATLAB's ``std``
            (N - 1), which the authors' Fig. 5 took (:func:`amex.sim.metrics.mean_2std`). It
            changes no episode.
        implementation: ``ours`` or ``original``: amex, dmp and cr as the authors' harness ran
            them (:data:`amex.methods.ORIGINAL_METHODS`); other methods have only one.
        log: ``none`` or ``full`` (one MCAP file per episode).
        log_compression: how a log's chunks are compressed: ``lz4`` (the default: ~1 point of
            an episode less than zstd, files 14-20 % larger), ``zstd`` (the smallest files) or
            ``none`` (~1.5 points less than lz4, files 1.7-2.2 times larger); docs/logs.md. It
            changes no episode.
        shards: split the ``episodes`` environments over this many runs
        (:mod:`amex.experiment.shards`).
        shard: which of them this run executes, ``0 <= shard < shards``: the environments
            ``shard, shard + shards, ...``.
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
    episodes: int = field(default=150, metadata=limits(ge=1, le=MAX_EPISODES))
    seed: int = 0
    outer_hz: float = field(default=100.0, metadata=limits(gt=0))
    inner_hz: float = field(default=1000.0, metadata=limits(gt=0))
    max_time: float = field(default=10.0, metadata=limits(gt=0))
    success_radius: float = field(default=0.03, metadata=limits(gt=0))
    stop_radius: float = field(default=0.03, metadata={**scaled(1), **limits(gt=0)})
    sim: str = "dynamic"
    state_lag: bool = False
    final_time: str = "elapsed"
    std_ddof: int = field(default=0, metadata=limits(ge=0, le=1))
    implementation: str = "ours"
    log: str = "none"
    log_compression: str = LOG_COMPRESSIONS[0]
    shards: int = field(default=1, metadata=limits(ge=1))
    shard: int = 0

    @property
    def envs(self) -> range:
        """The environments this run executes (all ``episodes`` unless sharded)."""
        return shard_envs(self.episodes, self.shards, self.shard)

    @property
    def loop(self) -> LoopConfig:
        """The episode loop's settings."""
        scale = float(self.scenario.scale)
        stop = scale_value(self.stop_radius, scale, scale_power(RunConfig, "stop_radius"))
        return LoopConfig(
            outer_hz=float(self.outer_hz),
            inner_hz=float(self.inner_hz),
            max_time=float(self.max_time),
            success_radius=float(self.success_radius),
            stop_radius=stop,
            kinematic=self.sim == "kinematic",
            state_lag=bool(self.state_lag),
            final_time=str(self.final_time),
        )

    def scene(self) -> ScenarioConfig:
        """The scene distributions in the scene's units (:mod:`amex.core.scaling`).

        The one place they are converted: :mod:`amex.sim.scenario` takes them so.
        """
        return to_scene_units(self.scenario, float(self.scenario.scale))

    def method_config(self) -> Any:
        """The method's configuration in the scene's units (:mod:`amex.core.scaling`)."""
        return to_scene_units(self.method, float(self.scenario.scale))

    def gains(self) -> OSCGains:
        """Inner-controller gains: the method's task gains plus the shared terms."""
        c = to_scene_units(self.controller, float(self.scenario.scale))
        return OSCGains.of(c, self.method.pos, self.method.dir)


def validate(config: RunConfig) -> None:
    """Raise :class:`ConfigError` naming the first invalid value and the valid choices.

    Besides the checks below, :func:`amex.core.schema.check_tree` checks every field of the tree: no
    non-finite number anywhere, no negative scalar unless the field allows it, no unknown key, and
    each node's own ``validate()``. Whether the method can be built from its parameters is
    checked by :func:`amex.experiment.runner.preflight`.
    """
    if isinstance(config.task, bool) or config.task not in TASKS:
        raise ConfigError.invalid("task", config.task, TASKS)
    name = getattr(config.method, "name", None)
    if name not in METHODS:
        raise ConfigError.invalid("method", name, sorted(METHODS))
    check_tree(config)
    ShardSpec(config.shard, config.shards, config.episodes)  # raises for a bad split
    if config.log not in LOG_LEVELS:
        raise ConfigError.invalid("log", config.log, LOG_LEVELS)
    if config.log_compression not in LOG_COMPRESSIONS:
        raise ConfigError.invalid("log_compression", config.log_compression, LOG_COMPRESSIONS)
    if config.implementation not in IMPLEMENTATIONS:
        raise ConfigError.invalid("implementation", config.implementation, IMPLEMENTATIONS)
    metrics = {"plan.metric": config.plan.metric, "controller.metric": config.controller.metric}
    for key, value in metrics.items():
        if value not in METRICS:
            raise ConfigError.invalid(key, value, METRICS)
    if config.sim not in SIMULATIONS:
        raise ConfigError.invalid("sim", config.sim, SIMULATIONS)
    if config.sim == "kinematic" and config.mismatch != type(config.mismatch)():
        raise ConfigError(
            f"invalid mismatch={config.mismatch} with sim=kinematic; "
            "valid: the defaults (a kinematic simulation has no dynamics to mismatch)"
        )
    if config.sim == "kinematic" and config.controller.disturbance != "none":
        raise ConfigError(
            f"invalid controller.disturbance={config.controller.disturbance!r} with "
            "sim=kinematic; valid: none (a kinematic simulation has no torques to compensate)"
        )
    config.loop.validate()
    steps = config.max_time * config.inner_hz
    if steps > MAX_EPISODE_STEPS:
        raise ConfigError(
            f"invalid max_time={config.max_time:g} with inner_hz={config.inner_hz:g}: "
            f"{steps:.3g} inner steps per episode; valid: max_time x inner_hz <= "
            f"{MAX_EPISODE_STEPS:,} ({MAX_EPISODE_STEPS / config.inner_hz:g} s at this rate)"
        )
    if config.loop.stop_radius > config.success_radius:
        scale = config.scenario.scale
        raise ConfigError(
            f"invalid scenario.scale={scale:g} with stop_radius={config.stop_radius:g}: the "
            f"episode would stop {config.loop.stop_radius:.3g} m from the goal (stop_radius x "
            f"scale), beyond success_radius = {config.success_radius:g} m; valid: "
            f"scenario.scale <= {config.success_radius / config.stop_radius:g} at this "
            "stop_radius (or a smaller stop_radius)"
        )
    robot = load_robot(config.robot)  # a description the loop cannot use is a config error
    radii, n_capsules = config.controller.proxy_arm_radii, len(robot.capsules)
    if radii and (len(radii) != n_capsules or min(radii) <= 0.0):
        raise ConfigError.invalid(
            "controller.proxy_arm_radii",
            radii,
            f"[] or {n_capsules} radii > 0 [m], one per capsule",
        )
    plan = config.plan
    if not (plan.dt > 0 and plan.duration > 0):
        raise ConfigError.invalid("plan.dt", plan.dt, "dt > 0 and duration > 0 [s]")
    if not math.isclose(plan.duration / plan.dt, round(plan.duration / plan.dt), abs_tol=1e-9):
        raise ConfigError.invalid("plan.duration", plan.duration, "an integer multiple of plan.dt")
    if not 2 <= plan.steps <= MAX_PLAN_STEPS:
        raise ConfigError.invalid(
            "plan.dt", plan.dt, f"a spacing giving 2..{MAX_PLAN_STEPS} knots over plan.duration"
        )
    if plan.max_iterations < 1:
        raise ConfigError.invalid("plan.max_iterations", plan.max_iterations, "an integer >= 1")
