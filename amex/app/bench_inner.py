"""The 1 kHz inner step timed inside real episodes, against its library floor (issue #29).

:func:`measure` runs environments of a task with a method exactly as a run builds them
(:func:`amex.experiment.runner.setup`), with a probe (:class:`amex.sim.episode.Probe`) that stamps
thread CPU time (``time.thread_time_ns``) and wall time at the start of every inner step and keeps
the simulator's state there. A step's time runs from the end of its probe call to the start of the
next one, so the probe's own work is not counted; an outer step's time includes the method's step
(timed apart, :attr:`EpisodeSteps.method_cpu`).

The floor of a step is the Pinocchio, coal and MuJoCo calls the step must make, replayed alone on
the state of the same step, on a copy of the episode's world, by the probe at the start of the
next step (so that step and floor are timed under the same load of the machine): forward
kinematics with velocities, the joint Jacobians, the TCP placement, Jacobian and classical
acceleration, the geometry placements and coal's distances (scenes with obstacles), the inverse
dynamics (RNEA) and ``mj_step`` (``sim=kinematic``: ``mj_kinematics`` and ``mj_collision`` where
obstacles can be touched, no RNEA). A step is *in the margin* when coal's closest arm-obstacle
pair is nearer than the controller's margin: the collision task is active there.

:func:`inner_step` gives the inner steps (outer steps left out) in one clock; nothing here asserts
a time. ``python -m amex.app.bench_inner --tasks 0 3 --methods amex dmp`` prints the table.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from typing import Any, NamedTuple  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

from amex.app.argparsing import OneLineParser  # noqa: E402
from amex.control.collision import CollisionModel  # noqa: E402
from amex.sim.scenario import Scenario, make_scenario  # noqa: E402
from amex.sim.simulation import Simulation  # noqa: E402

_LWA = pin.LOCAL_WORLD_ALIGNED


class EpisodeSteps(NamedTuple):
    """Every step of the measured episodes, in order (one entry per executed step).

    Attributes:
        step_cpu: thread CPU time of the step [s].
        step_wall: wall time of the step [s].
        floor_cpu: thread CPU time of its library calls alone [s].
        floor_wall: wall time of its library calls alone [s].
        in_margin: the collision task is active at the step.
        outer: the step is an outer step (the method's step ran in it).
        method_cpu: the method's own step at outer steps, 0 elsewhere [s] (thread CPU).
    """

    step_cpu: np.ndarray
    step_wall: np.ndarray
    floor_cpu: np.ndarray
    floor_wall: np.ndarray
    in_margin: np.ndarray
    outer: np.ndarray
    method_cpu: np.ndarray


class StepTimes(NamedTuple):
    """The inner steps (outer steps left out) of :func:`inner_step`, in one clock [s]."""

    step_times: np.ndarray
    floor_times: np.ndarray
    in_margin_mask: np.ndarray


class _Floor:
    """The library calls of one step, alone, on a copy of the episode's world (module notes)."""

    def __init__(
        self, robot: Any, scenario: Scenario, inner_hz: float, kinematic: bool, margin: float
    ) -> None:
        self.robot, self.kinematic, self.margin = robot, kinematic, margin
        self.pdata = robot.model.createData()
        sim = Simulation(robot, scenario, inner_hz)
        self.mjm, self.mjd = sim.model, sim.data
        self.collision = (
            CollisionModel(robot, scenario.obstacle_radii) if scenario.n_obstacles else None
        )
        self.qdd = np.zeros(robot.nv)

    def __call__(self, state: tuple[np.ndarray, ...], tau: np.ndarray) -> tuple[int, int, bool]:
        """Thread CPU and wall time [ns] of the calls at ``state`` with ``tau``; in the margin."""
        robot, mjm, mjd, pdata = self.robot, self.mjm, self.mjd, self.pdata
        model, fid, zero = robot.model, robot.tcp_frame_id, robot.zero_velocity
        q, v, mocap, warm = state
        mjd.qpos[:], mjd.qvel[:], mjd.qfrc_applied[:] = q, v, tau
        mjd.mocap_pos[:], mjd.qacc_warmstart[:] = mocap, warm
        collision = self.collision
        if collision is not None:
            collision.set_obstacles(mocap)
            gm, gd = collision.geom_model, collision.geom_data
        tic_wall, tic_cpu = time.perf_counter_ns(), time.thread_time_ns()
        pin.forwardKinematics(model, pdata, q, v, zero)
        pin.computeJointJacobians(model, pdata)
        pin.updateFramePlacement(model, pdata, fid)
        pin.getFrameJacobian(model, pdata, fid, _LWA)
        pin.getFrameClassicalAcceleration(model, pdata, fid, _LWA)
        if collision is not None:
            pin.updateGeometryPlacements(model, pdata, gm, gd)
            closest = pin.computeDistances(gm, gd)
        if not self.kinematic:
            pin.rnea(model, pdata, q, v, self.qdd)
            mujoco.mj_step(mjm, mjd)
        elif collision is not None:
            mujoco.mj_kinematics(mjm, mjd)
            mujoco.mj_collision(mjm, mjd)
        cpu = time.thread_time_ns() - tic_cpu
        wall = time.perf_counter_ns() - tic_wall
        inside = collision is not None and gd.distanceResults[closest].min_distance < self.margin
        return cpu, wall, inside


class _Stamps:
    """The probe: stamps at each step's start; the previous step's floor, timed in between."""

    def __init__(self, floor: _Floor) -> None:
        self.floor = floor
        self.start_cpu: list[int] = []  # when the probe was entered (the previous step's end)
        self.start_wall: list[int] = []
        self.end_cpu: list[int] = []  # when it returned (the step's start)
        self.end_wall: list[int] = []
        self.floors: list[tuple[int, int, bool]] = []
        self._state: tuple[np.ndarray, ...] = ()

    def __call__(self, k: int, data: mujoco.MjData) -> None:
        cpu, wall = time.thread_time_ns(), time.perf_counter_ns()
        if k:  # the step that just ended, its torque still in qfrc_applied
            self.floors.append(self.floor(self._state, data.qfrc_applied.copy()))
        state = (data.qpos.copy(), data.qvel.copy(), data.mocap_pos.copy())
        self._state = (*state, data.qacc_warmstart.copy())
        self.start_cpu.append(cpu)
        self.start_wall.append(wall)
        self.end_wall.append(time.perf_counter_ns())
        self.end_cpu.append(time.thread_time_ns())


def measure(
    task: int = 3,
    method: str = "amex",
    envs: Sequence[int] = range(1),
    overrides: Sequence[str] = (),
) -> EpisodeSteps:
    """Every step of ``envs`` of ``task`` with ``method``, timed, and its floor (module notes).

    Args:
        task: the task, 0-4.
        method: the method's registry key.
        envs: the environments.
        overrides: further Hydra overrides (e.g. ``experiment=original``).
    """
    from amex.app.compose import load_config
    from amex.experiment.runner import prepare, setup
    from amex.sim.episode import run_episode

    config = load_config([f"method={method}", f"task={task}", *overrides])
    run = setup(config, prepare(config))
    context = run.context
    parts: list[list[np.ndarray]] = [[] for _ in EpisodeSteps._fields]
    for env in envs:
        instance = run.method(context.plan, run.params, run.outer_dt, context.robot)
        method_cpu: list[float] = []
        original = instance.step

        def timed(obs, original=original, method_cpu=method_cpu):  # the method's own step
            cpu = time.thread_time_ns()
            out = original(obs)
            method_cpu.append((time.thread_time_ns() - cpu) * 1e-9)
            return out

        instance.step = timed  # type: ignore[method-assign]
        scenario = make_scenario(
            run.scene, task, run.seed, env, context.plan.y[0, :3], context.plan.duration
        )
        floor = _Floor(
            context.robot, scenario, config.inner_hz, run.loop.kinematic, run.gains.margin
        )
        stamps = _Stamps(floor)
        world = {**run.world, "reference_path": context.plan.y[:, :3]}
        run_episode(context.robot, instance, scenario, run.gains, run.loop, probe=stamps, **world)
        n = len(stamps.floors)  # steps that ran to their end (the last probe call ends none)
        step_cpu = (np.array(stamps.start_cpu[1 : n + 1]) - np.array(stamps.end_cpu[:n])) * 1e-9
        step_wall = (np.array(stamps.start_wall[1 : n + 1]) - np.array(stamps.end_wall[:n])) * 1e-9
        floor_cpu = np.array([f[0] for f in stamps.floors]) * 1e-9
        floor_wall = np.array([f[1] for f in stamps.floors]) * 1e-9
        inside = np.array([f[2] for f in stamps.floors], dtype=bool)
        outer = np.arange(n) % run.loop.substeps == 0
        own = np.zeros(n)
        own[outer] = method_cpu[: int(outer.sum())]
        for part, values in zip(
            parts, (step_cpu, step_wall, floor_cpu, floor_wall, inside, outer, own), strict=True
        ):
            part.append(values)
    return EpisodeSteps(*(np.concatenate(p) for p in parts))


def inner_step(
    task: int = 3,
    method: str = "amex",
    envs: Sequence[int] = range(1),
    clock: str = "thread",
    overrides: Sequence[str] = (),
) -> StepTimes:
    """The inner steps (outer steps left out) of :func:`measure`, in ``clock`` (thread or wall)."""
    if clock not in ("thread", "wall"):
        raise ValueError(f"invalid clock={clock!r}; valid: thread, wall")
    steps = measure(task, method, envs, overrides)
    keep = ~steps.outer
    step, floor = (
        (steps.step_cpu, steps.floor_cpu)
        if clock == "thread"
        else (steps.step_wall, steps.floor_wall)
    )
    return StepTimes(step[keep], floor[keep], steps.in_margin[keep])


def table_rows(steps: EpisodeSteps) -> list[str]:
    """Median and p95 [us] of the inner steps in and out of the margin, and the outer steps."""
    rows = []
    inner = ~steps.outer
    for label, mask in (
        ("all", inner),
        ("out of margin", inner & ~steps.in_margin),
        ("in margin", inner & steps.in_margin),
    ):
        if not mask.any():
            continue
        s, f = steps.step_cpu[mask], steps.floor_cpu[mask]
        sw, fw = steps.step_wall[mask], steps.floor_wall[mask]
        rows.append(
            f"  inner {label:<14} n={int(mask.sum()):6d}  thread CPU: step {_us(np.median(s))} "
            f"(p95 {_us(np.percentile(s, 95))}), floor {_us(np.median(f))}, ratio "
            f"{np.median(s) / np.median(f):4.2f};  wall: step {_us(np.median(sw))} "
            f"(p95 {_us(np.percentile(sw, 95))}), floor {_us(np.median(fw))}"
        )
    outer = steps.outer
    loop = steps.step_cpu[outer] - steps.method_cpu[outer]
    rows.append(
        f"  outer steps    n={int(outer.sum()):6d}  thread CPU: step without the method's own "
        f"{_us(np.median(loop))} (p95 {_us(np.percentile(loop, 95))}); method's step "
        f"{_us(np.median(steps.method_cpu[outer]))}"
    )
    return rows


def _us(x: float | np.floating) -> str:
    return f"{float(x) * 1e6:6.1f} us"


def main(argv: list[str] | None = None) -> None:
    """Print the inner-step table for the given tasks and methods."""
    parser = OneLineParser(prog="amex-bench-inner", description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, nargs="*", choices=range(5), default=[0, 3])
    parser.add_argument("--methods", nargs="*", default=["amex"])
    parser.add_argument("--episodes", type=int, default=1, help="environments per task")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides, e.g. experiment=original")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes {args.episodes}: valid: an integer >= 1")
    for method in args.methods:
        for task in args.tasks:
            steps = measure(task, method, range(args.episodes), args.overrides)
            print(f"Task {task}, {method} ({args.episodes} env, {len(steps.outer)} steps)")
            print("\n".join(table_rows(steps)))


if __name__ == "__main__":
    main()
