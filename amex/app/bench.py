"""``make bench``: the costs that matter, each beside its floor, so that a regression is a ratio.

* inner 1 kHz step (robot state, OSC, collision task, inverse dynamics, ``mj_step``) inside real
  episodes, Task 0 and Task 3 (AMEX, DMP, CR), in and out of the collision margin: median and
  p95 of its thread CPU time beside its library floor, the same Pinocchio, coal and MuJoCo
  calls replayed alone on the same state (:mod:`amex.app.bench_inner`);
* start-up of ``amex-run``, whole-process CPU, warm and with a cold Numba cache, beside the
  interpreter importing the libraries a run calls (:mod:`amex.app.bench_startup`);
* ``log=full``: thread CPU of logged episodes over the same episodes unlogged;
* Task-0 episodes per robot (``sim=dynamic`` and ``kinematic``), the reference plan cold and from
  the disk cache;
* each registered method's outer step (``Method.step``) on ``--tasks`` (default 1-4), over
  ``--episodes`` environments: median and p95 of its thread CPU time (``time.thread_time_ns``),
  its wall median, and beside it CR's kernel floor (:mod:`amex.app.bench_cr`) or the method's
  target (AMEX <= 5 us, issue #29; the reactive methods', issue #26); the replanners' (CR,
  MPPI) max and fraction over the 10 ms period.

Nothing here asserts a time (tests never time things).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import math  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from amex.app.argparsing import OneLineParser  # noqa: E402
from amex.experiment.config import RunConfig  # noqa: E402
from amex.experiment.runner import prepare, run_one  # noqa: E402
from amex.methods import METHODS  # noqa: E402
from amex.plan.cache import reference_plan, solve_reference  # noqa: E402
from amex.sim.scenario import make_scenario  # noqa: E402


def _config(method: str, task: int = 0) -> RunConfig:
    config = RunConfig(task=task)
    config.method = METHODS[method].config_class()
    return config


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


#: The replanners whose outer step is also reported with its max and deadline misses.
REPLANNERS = ("cr", "mppi")
#: Targets of the outer steps [s] (issue #29: AMEX; issue #26: the reactive methods).
STEP_TARGETS = {"amex": 5e-6, "rmpflow": 5e-4, "cbf_ik": 5e-4, "amex_cbf": 5e-4, "dmp_avoid": 1e-4}


def clock_cost(samples: int = 20_000) -> float:
    """Median thread CPU time [s] an empty interval reads: the clock's own cost in every figure.

    ``time.thread_time_ns`` is a system call where the kernel offers no fast path for it (in a
    virtual machine ~0.9 us); each per-step time here, and the episodes' ``compute_cpu_*``,
    reads the clock twice and so carries about this much beside the step's own work.
    """
    clock = time.thread_time_ns
    empty = np.empty(samples)
    for i in range(samples):
        start = clock()
        empty[i] = clock() - start
    return float(np.median(empty)) * 1e-9


def _us(x: float | np.floating) -> str:
    return f"{float(x) * 1e6:9.1f} us"


def _ratio(value: float, floor: float) -> str:
    return f"{value / floor:5.2f}x" if floor > 0 else "    -"


def main(argv: list[str] | None = None) -> None:
    """Print the benchmark report: each figure beside its floor, so a regression is a ratio."""
    parser = OneLineParser(prog="amex-bench", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    parser.add_argument(
        "--episodes", type=int, default=1, help="environments per (method, task) step timing"
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
        help="tasks on which every method's outer step is timed",
    )
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes {args.episodes}: valid: an integer >= 1")
    envs = range(args.episodes)
    if not args.steps_only:
        _print_inner(args.quick)
        _print_startup(args.quick)
        _print_log_cost(args.quick)
        _print_platform(args.quick)
    print("outer step of each method (thread CPU time per step; `floor`: its compiled kernels")
    print("and LAPACK solves timed alone on the same inputs, where a method has one)")
    clock = clock_cost()
    print(f" the clock: an empty interval reads {_us(clock).strip()} of thread CPU (in each)")
    for name in args.methods or sorted(METHODS):
        for task in args.tasks:
            _print_method(name, task, envs, clock)


def _print_method(name: str, task: int, envs: range, clock: float = 0.0) -> None:
    """One method's outer step on one task: median, p95 (thread CPU), floor or target."""
    floor = math.nan
    if name == "cr":
        from amex.app.bench_cr import cr_floor

        steps = cr_floor(task, envs)
        cpus, walls = np.asarray(steps.step_cpu), np.asarray(steps.step_wall)
        floor = float(np.median(steps.floor_cpu))
    else:
        walls_list, cpus_list = bench_method_steps(name, task, envs)
        cpus, walls = np.asarray(cpus_list), np.asarray(walls_list)
    median, p95 = float(np.median(cpus)), float(np.percentile(cpus, 95))
    beside = ""
    if math.isfinite(floor):
        beside = f"  floor {_us(floor)}  ratio {_ratio(median, floor)}"
    elif name in STEP_TARGETS:
        beside = f"  target {_us(STEP_TARGETS[name])}  net of the clock {_us(median - clock)}"
    extra = ""
    if name in REPLANNERS:
        extra = f"  max {_us(cpus.max())}  over 10 ms {np.mean(cpus > 0.01):.4f}"
    print(
        f"  {name:<10} Task {task} ({len(envs)} env, {len(cpus):5d} steps): median {_us(median)}"
        f"  p95 {_us(p95)}  wall median {_us(np.median(walls))}{beside}{extra}"
    )


def _print_inner(quick: bool) -> None:
    """The 1 kHz inner step inside real episodes beside its library floor (bench_inner)."""
    from amex.app.bench_inner import measure, table_rows

    envs = range(1 if quick else 2)
    print("inner 1 kHz step inside real episodes (thread CPU; floor: its Pinocchio, coal and")
    print("MuJoCo calls replayed alone on the same state)")
    for task, method in ((0, "track"), (3, "amex"), (3, "dmp"), (3, "cr")):
        steps = measure(task, method, envs)
        print(f" Task {task}, {method} ({len(envs)} env, {len(steps.outer)} steps)")
        print("\n".join(table_rows(steps)))


def _print_startup(quick: bool) -> None:
    """Start-up CPU of amex-run, warm and cold, beside its floor (bench_startup)."""
    from amex.app.bench_startup import STEPS, startup_times

    times = startup_times(2 if quick else 5)
    floor = statistics.median(times.floor)
    numba_floor = statistics.median(times.numba_floor)
    print(f"start-up of amex-run (whole process, user + system CPU, one {STEPS}-step episode;")
    print(" floor: the interpreter importing the libraries a run calls; Numba floor: and Numba")
    print(" imported and its CPU target initialised, as a run of Numba-compiled kernels needs;")
    print(" Numba's JIT: the kernels built ahead of time off, AMEX_AOT=0)")
    rows = (
        ("warm caches", times.warm),
        ("cold Numba cache", times.cold),
        ("warm, Numba's JIT", times.jit),
    )
    for label, values in rows:
        median = statistics.median(values)
        print(
            f"  {label:<18} median of {len(values)}: {median:6.3f} s  (min {min(values):.3f}, "
            f"max {max(values):.3f})  floor {floor:6.3f} s  ratio {_ratio(median, floor)}, "
            f"Numba floor {numba_floor:6.3f} s  ratio {_ratio(median, numba_floor)}"
        )
    _print_startup_phases(2 if quick else 3)


def _print_startup_phases(repeats: int) -> None:
    """A warm start-up's CPU, phase by phase (bench_startup.startup_phases), medians."""
    from amex.app.bench_startup import PHASES, startup_phases

    phases = startup_phases(repeats)
    median = {key: statistics.median(values) for key, values in phases.items()}
    print(f" a warm start-up phase by phase (process CPU, median of {repeats}):")
    for key, label in PHASES:
        print(f"  {label:<68} {median[key]:6.3f} s")
    hydra = median["schemas"] + median["composition"] + median["hydra_job"]
    below = median["libraries"] + median["numba"] + median["interpreter"] + hydra
    print(
        f"  whole process {median['total']:.3f} s; of it Hydra's ConfigStore, composition and "
        f"job {hydra:.3f} s, which with the libraries, the kernels and the interpreter make "
        f"{below:.3f} s before any of amex's own work"
    )


def _print_log_cost(quick: bool) -> None:
    """What ``log=full`` adds to an episode's thread CPU (:mod:`amex.app.bench_log`)."""
    from amex.app.bench_log import log_overhead

    print(
        "log=full: thread CPU of each episode logged over the same episode unlogged"
        + ("" if quick else " (medians of 3 rounds)")
    )
    for method in ("amex", "dmp", "cr"):
        for task in (1, 2, 3, 4):
            envs, rounds = (range(2), 1) if quick else (range(4), 3)
            times = log_overhead(task, method, envs, rounds=rounds, verbose=False)
            total = float(np.sum(times.logged_cpu) / np.sum(times.plain_cpu)) - 1.0
            each = times.overhead()
            floor = float(np.sum(times.floor_cpu) / np.sum(times.plain_cpu))
            replay = float(np.sum(times.replay_cpu) / np.sum(times.plain_cpu)) - 1.0
            print(
                f"  {method:<5} Task {task}: +{total * 100:5.1f} % over its episodes (median "
                f"+{np.median(each) * 100:5.1f} %, p95 +{np.percentile(each, 95) * 100:5.1f} %);"
                f" floor (the SDK writing the same logs alone) +{floor * 100:4.1f} %, replayed in"
                f" the episode +{replay * 100:4.1f} %; target <= 15 %"
            )


def _print_platform(quick: bool) -> None:
    """The Task-0 episodes (per robot) and the reference plan."""
    config = _config("track")
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
