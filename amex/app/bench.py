"""``make bench``: medians of the costs that matter, printed as a table.

* inner step: one 1 kHz step (robot state, OSC solve, inverse dynamics, mj_step), median over a
  Task-0 episode's steps, measured inside a real episode loop;
* Task-0 episode: wall time of a whole episode with ``track`` (and its real-time factor), on the
  Panda, then per robot of ``conf/robot/`` with ``sim=dynamic`` and ``sim=kinematic``;
* reference plan: cold solve, and a disk-cache hit;
* each registered method's own outer step (``Method.step``), median, mean and p95 over the
  steps of Task-3 episodes (``--episodes N`` environments, default 1; ``--methods`` a subset),
  in wall time and in thread CPU time (``time.thread_time_ns``; the reactive methods' targets,
  issue #26: rmpflow, cbf_ik, amex_cbf <= 0.5 ms, dmp_avoid <= 0.1 ms, beside AMEX's);
* the replanners' outer step (CR and MPPI) on ``--tasks`` (default 1-4): median, p95 and max of
  its thread CPU time (what ``deadline_misses`` counts) and the fraction over the 10 ms period.

Timings use ``time.perf_counter_ns``; nothing here asserts a time (tests never time things).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from amex.app.argparsing import OneLineParser  # noqa: E402
from amex.control.collision import CollisionModel  # noqa: E402
from amex.control.osc import Command, OperationalSpaceController  # noqa: E402
from amex.control.state import RobotState  # noqa: E402
from amex.experiment.config import RunConfig  # noqa: E402
from amex.experiment.runner import prepare, run_one  # noqa: E402
from amex.methods import METHODS  # noqa: E402
from amex.plan.cache import reference_plan, solve_reference  # noqa: E402
from amex.sim.scenario import make_scenario  # noqa: E402
from amex.sim.simulation import Simulation  # noqa: E402


def _config(method: str, task: int = 0) -> RunConfig:
    config = RunConfig(task=task)
    config.method = METHODS[method].config_class()
    return config


def bench_inner_step(config: RunConfig, steps: int = 4000) -> list[float]:
    """Per-step wall times [s] of the inner loop following the reference plan in Task 0."""
    context = prepare(config)
    robot, plan = context.robot, context.plan
    scenario = make_scenario(config.scene(), 0, 0, 0, plan.y[0, :3], plan.duration)
    sim = Simulation(robot, scenario, config.inner_hz)
    collision = CollisionModel(robot, scenario.obstacle_radii)
    osc = OperationalSpaceController(robot, config.gains(), collision)
    method = METHODS["track"](plan, METHODS["track"].config_class(), 0.01, robot)
    pdata = robot.model.createData()
    from amex.methods.base import Observation

    times = []
    command = Command()
    for k in range(steps):
        tic = time.perf_counter_ns()
        state = RobotState(robot, pdata, sim.data.qpos.copy(), sim.data.qvel.copy())
        if k % 10 == 0:
            obs = Observation(k * 1e-3, state.q, state.v, state.y, state.yd, plan.goal)
            command = method.step(obs)
        tau = osc.torque(state, command)
        sim.data.qfrc_applied[:] = tau
        mujoco.mj_step(sim.model, sim.data)
        times.append((time.perf_counter_ns() - tic) * 1e-9)
    return times


def bench_episode(config: RunConfig, repeats: int = 5) -> list[float]:
    """Wall times [s] of whole Task-0 episodes."""
    context = prepare(config)
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        result = run_one(config, context, 0)
        times.append(time.perf_counter() - tic)
    return times + [result.final_time]


def bench_robot_episode(robot: str, sim: str, repeats: int) -> tuple[list[float], float]:
    """Wall times [s] of Task-0 ``track`` episodes of ``robot`` simulated as ``sim``."""
    from amex.app.compose import load_config

    config = load_config([f"robot={robot}", f"sim={sim}", "method=track", "task=0"])
    walls = bench_episode(config, repeats)
    return walls[:-1], walls[-1]


def bench_plan(config: RunConfig, repeats: int = 3) -> tuple[list[float], list[float]]:
    """Cold solve times [s] and cache-hit times [s] of the reference plan."""
    context = prepare(config)
    goal = np.asarray(config.scenario.reference_goal, dtype=float)
    axis = np.asarray(config.scenario.goal_axis, dtype=float)
    cold = []
    for _ in range(repeats):
        tic = time.perf_counter()
        solve_reference(context.robot, config.plan, goal, axis)
        cold.append(time.perf_counter() - tic)
    hits = []
    with tempfile.TemporaryDirectory() as tmp:
        reference_plan(context.robot, config.plan, goal, axis, Path(tmp))
        for _ in range(20):
            tic = time.perf_counter()
            reference_plan(context.robot, config.plan, goal, axis, Path(tmp))
            hits.append(time.perf_counter() - tic)
    return cold, hits


def bench_method_steps(
    name: str, task: int = 3, envs: range = range(1)
) -> tuple[list[float], list[float]]:
    """Per-step wall and thread CPU times [s] of the outer step of ``name`` on ``envs`` of ``task``.

    The method as a run builds it: ``conf/method/<name>.yaml`` composed, lengths in the scene's
    units (:func:`amex.experiment.runner.setup`); seed 0.
    """
    from amex.app.compose import load_config
    from amex.experiment.runner import setup
    from amex.sim.episode import run_episode

    config = load_config([f"method={name}", f"task={task}"])
    run = setup(config, prepare(config))
    context = run.context
    method = run.method(context.plan, run.params, run.outer_dt, context.robot)
    walls: list[float] = []
    cpus: list[float] = []
    original = method.step

    def timed(obs):  # same measurement as the episode loop, kept per step
        tic, cpu = time.perf_counter_ns(), time.thread_time_ns()
        out = original(obs)
        cpus.append((time.thread_time_ns() - cpu) * 1e-9)
        walls.append((time.perf_counter_ns() - tic) * 1e-9)
        return out

    method.step = timed  # type: ignore[method-assign]
    for env in envs:
        scenario = make_scenario(
            run.scene, task, run.seed, env, context.plan.y[0, :3], context.plan.duration
        )
        run_episode(context.robot, method, scenario, run.gains, run.loop)
    return walls, cpus


#: The replanners whose outer step is timed on every task (issue #27: MPPI beside CR).
REPLANNERS = ("cr", "mppi")


def _us(x: float | np.floating) -> str:
    return f"{float(x) * 1e6:9.1f} us"


def main(argv: list[str] | None = None) -> None:
    """Print the benchmark table."""
    parser = OneLineParser(prog="amex-bench", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    parser.add_argument(
        "--episodes", type=int, default=1, help="Task-3 environments per method's step timing"
    )
    parser.add_argument(
        "--methods", nargs="*", choices=sorted(METHODS), help="methods to time (default: all)"
    )
    parser.add_argument("--steps-only", action="store_true", help="only the methods' outer steps")
    parser.add_argument(
        "--tasks",
        type=int,
        nargs="*",
        choices=range(5),
        default=[1, 2, 3, 4],
        help=f"tasks on which the replanners ({', '.join(REPLANNERS)}) are timed on CPU time",
    )
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes {args.episodes}: valid: an integer >= 1")
    if not args.steps_only:
        _print_platform(args.quick)
    for name in args.methods or sorted(METHODS):
        steps, cpu = bench_method_steps(name, envs=range(args.episodes))
        p95 = float(np.percentile(steps, 95))
        print(
            f"method {name:<9} outer step on Task 3 ({args.episodes} env), median of "
            f"{len(steps)}: {_us(np.median(steps))}  (mean {_us(np.mean(steps))}, p95 {_us(p95)});"
            f" thread CPU median {_us(np.median(cpu))}, p95 {_us(np.percentile(cpu, 95))}"
        )
    replanners = [m for m in REPLANNERS if m in (args.methods or REPLANNERS)]
    for name in replanners:
        for task in args.tasks:
            walls, cpus = bench_method_steps(name, task, envs=range(args.episodes))
            times, period = np.asarray(cpus), 0.01
            print(
                f"method {name:<9} Task {task} ({args.episodes} env, {len(times)} steps), thread "
                f"CPU: median {_us(np.median(times))}, p95 {_us(np.percentile(times, 95))}, max "
                f"{_us(times.max())}; wall median {_us(np.median(walls))}; over 10 ms:"
                f" {np.mean(times > period):.4f}"
            )


def _print_platform(quick: bool) -> None:
    """The inner step, the Task-0 episode and the reference plan."""
    config = _config("track")
    inner = bench_inner_step(config, 2000 if quick else 6000)
    print(f"inner step (state + OSC + mj_step), median of {len(inner)}: {_us(np.median(inner))}")
    episode = bench_episode(config, 2 if quick else 5)
    final_time, walls = episode[-1], episode[:-1]
    wall = statistics.median(walls)
    print(
        f"Task-0 episode ({final_time:.2f} s simulated), median wall: {wall:9.3f} s  "
        f"(real-time factor {final_time / wall:.1f})"
    )
    for robot in ("panda", "chain7", "ur5"):
        for sim in ("dynamic", "kinematic"):
            walls, final_time = bench_robot_episode(robot, sim, 2 if quick else 5)
            wall = statistics.median(walls)
            print(
                f"Task-0 episode, {robot:<6} {sim:<9} ({final_time:.2f} s simulated), median wall:"
                f" {wall:7.3f} s  (real-time factor {final_time / wall:.1f})"
            )
    cold, hits = bench_plan(config, 1 if quick else 3)
    print(f"reference plan, cold solve, median of {len(cold)}: {statistics.median(cold):9.3f} s")
    hit = statistics.median(hits) * 1e3
    print(f"reference plan, cache hit, median of {len(hits)}: {hit:9.2f} ms")


if __name__ == "__main__":
    main()
