"""CR's outer step against its kernel floor (issue #29): ``python -m amex.app.bench_cr``.

The floor of one outer step is the time of the compiled work the step must do anyway, timed
alone on the same inputs: the Numba kernels of :mod:`amex.plan.kinematics_kernels` (frames,
capsule distances, near pairs, pair gradients, final terms), the sines and cosines of the
frames, the final terms' kinematics and LAPACK's banded Cholesky ``dpbsv``. The final terms'
kinematics are Pinocchio's three calls where the solve makes them, and the compiled loop's own
(:func:`~amex.plan.optimizer.compiled_loop.tcp_kinematics`) where it runs. Everything else the
step spends (numpy glue, allocations, Python, the band's fill, the small products) is the gap.

How: each environment runs twice on fresh CRs, which see the same observations (the same
numbers; checked step by step by their iterations). The first run times each outer step
(``Method.step``, thread CPU and wall) and nothing else: the step as a run pays it. Timed in the
second run instead, each step would follow the previous step's recording, which evicts the
step's code and data from the caches (:attr:`CRFloor.recorded_cpu`: 20-25 % more,
docs/results/speed.md). In the second run the trajectory solve each step ran is captured (its
arguments) and, after the step, solved again on the solver's Python path with the floor's
functions wrapped so that they record their arguments (copies): the step's own calls on the
step's own inputs (to the last bits where the compiled loop's kinematics round differently).
Where the step ran the compiled loop, each recorded Pinocchio triple becomes one
``tcp_kinematics`` call at the same joint angles. The recorded calls are then replayed back to
back, unwrapped, and timed as one block: the floor. Nothing here asserts a time.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator, Sequence  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from typing import Any, NamedTuple  # noqa: E402

import numpy as np  # noqa: E402

from amex.app.argparsing import OneLineParser  # noqa: E402

#: One recorded call: the function, its positional and keyword arguments.
Call = tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]


class CRFloor(NamedTuple):
    """Per outer step: the whole step's times and its floor's, thread CPU and wall [s].

    Attributes:
        step_cpu: thread CPU time of ``Method.step`` (timed alone: module notes).
        step_wall: its wall time.
        floor_cpu: thread CPU time of the step's kernel calls and solves, replayed alone.
        floor_wall: their wall time.
        iterations: solver iterations of the step (0 when it held).
        recorded_cpu: thread CPU time of the same step in the recording run, after the
            previous step's recording (shown beside ``step_cpu``, for what the recording costs).
    """

    step_cpu: list[float]
    step_wall: list[float]
    floor_cpu: list[float]
    floor_wall: list[float]
    iterations: list[int]
    recorded_cpu: list[float]


def _floor_functions() -> list[tuple[Any, str]]:
    """The floor's functions, as (owner, attribute) of their defining module or object."""
    import pinocchio as pin
    import scipy.linalg.lapack as lapack

    from amex.plan import kinematics_kernels as kk

    names = ("forward_frames", "capsule_sphere_distances", "near_pairs", "pair_gradients")
    owners: list[tuple[Any, str]] = [(kk, name) for name in names]
    owners.append((kk, "final_terms_joint"))
    owners += [(pin, "computeJointJacobians"), (pin, "updateFramePlacement")]
    owners += [(pin, "getFrameJacobian"), (lapack, "dpbsv"), (np, "sin"), (np, "cos")]
    return owners


def _snapshot(value: Any) -> Any:
    """A copy of an array argument, which a later call could change; other values as they are."""
    return value.copy(order="K") if isinstance(value, np.ndarray) else value


@contextmanager
def _recording(calls: list[Call]) -> Iterator[None]:
    """Wrap the floor's functions wherever amex holds them; each call appends (function, args).

    Only calls from Python are seen (a compiled kernel calling another is one call). Array
    arguments are copied (outputs included: the replay writes into its copies); Pinocchio's
    ``Data`` is not (the replay runs the calls in order, as the solve did).
    """
    import pinocchio as pin

    originals = {id(getattr(owner, name)) for owner, name in _floor_functions()}
    modules = [m for n, m in list(sys.modules.items()) if n.startswith("amex.") and m]
    patched = [(np, "sin", np.sin), (np, "cos", np.cos)]  # the frames' angles
    for module in [*modules, pin, sys.modules["scipy.linalg.lapack"]]:
        for attr, value in list(vars(module).items()):
            if id(value) in originals and value is not np.sin and value is not np.cos:
                patched.append((module, attr, value))

    def wrap(fn: Any) -> Callable[..., Any]:
        def recorded(*args: Any, **kwargs: Any) -> Any:
            calls.append((fn, tuple(_snapshot(a) for a in args), dict(kwargs)))
            return fn(*args, **kwargs)

        return recorded

    try:
        for module, attr, value in patched:
            setattr(module, attr, wrap(value))
        yield
    finally:
        for module, attr, value in patched:
            setattr(module, attr, value)


@contextmanager
def _unfused() -> Iterator[None]:
    """The solver's Python path: the floor's calls made from Python, where they can be seen.

    The compiled iteration makes the same calls on the same inputs from one compiled call
    (:mod:`amex.plan.optimizer.iteration_kernels`, bit for bit the same solve), where wrapping
    cannot see them; the recording solve runs the path that makes them one by one.
    """
    import amex.plan.optimizer.assembly as assembly

    bound = assembly.BOUND
    assembly.BOUND = False
    try:
        yield
    finally:
        assembly.BOUND = bound


def _as_compiled(calls: Sequence[Call], assembly: Any) -> list[Call]:
    """``calls`` with each Pinocchio triple replaced by the compiled loop's kinematics call."""
    import pinocchio as pin

    from amex.plan.optimizer.compiled_loop import tcp_kinematics

    local, parents, joint, point, rotation, support = assembly.compiled_robot[:6]
    n = len(support)
    out: list[Call] = []
    for fn, args, kwargs in calls:
        if fn is pin.computeJointJacobians:
            buffers = (np.empty((6, n)), np.empty((3, 3)), np.empty(3))
            kin_args = (local, parents, args[2], joint, point, rotation, support, *buffers)
            out.append((tcp_kinematics, kin_args, {}))
        elif fn not in (pin.updateFramePlacement, pin.getFrameJacobian):
            out.append((fn, args, kwargs))
    return out


def _replay(calls: Sequence[Call]) -> tuple[float, float]:
    """Thread CPU and wall time [s] of ``calls`` run back to back (on fresh copies)."""
    fresh = [(fn, tuple(_snapshot(a) for a in args), kw) for fn, args, kw in calls]
    tic, cpu = time.perf_counter_ns(), time.thread_time_ns()
    for fn, args, kw in fresh:
        fn(*args, **kw)
    cpu_time = (time.thread_time_ns() - cpu) * 1e-9
    return cpu_time, (time.perf_counter_ns() - tic) * 1e-9


def cr_floor(task: int, envs: range = range(1), overrides: Sequence[str] = ()) -> CRFloor:
    """CR's outer-step times and their floors on environments ``envs`` of ``task`` (seed 0).

    Args:
        task: 1-4.
        envs: the environments (episodes) run.
        overrides: further config overrides, e.g. ``("experiment=original",)`` for the authors'
            CR (Newton).

    Returns:
        Per outer step, the step's and the floor's times (module notes).

    Raises:
        RuntimeError: where the two runs of an environment did not take the same steps.
    """
    run = _cr_setup(task, overrides)
    result = CRFloor([], [], [], [], [], [])
    for env in envs:
        cpu, wall, iterations = _timed_episode(run, task, env)
        recorded = _recorded_episode(run, task, env, result)
        if recorded != iterations:  # the two runs must be the same steps to be paired
            raise RuntimeError(f"CR's two runs of task {task}, environment {env} differ")
        result.step_cpu.extend(cpu)
        result.step_wall.extend(wall)
    return result


def _recorded_episode(run: Any, task: int, env: int, result: CRFloor) -> list[int]:
    """Environment ``env`` with each step's floor recorded into ``result``; the steps' iterations.

    Appends to ``result``'s floor times, iterations and ``recorded_cpu`` (module notes).
    """
    import amex.plan.optimizer as optimizer

    context = run.context
    method = run.method(context.plan, run.params, run.outer_dt, context.robot)
    counted: list[int] = []
    solves: list[Call] = []
    names = ("solve_trajectory", "solve_trajectory_newton")
    solvers = {name: getattr(optimizer, name) for name in names}

    def captured(name: str) -> Callable[..., Any]:
        solver = solvers[name]

        def solve(*args: Any, **kwargs: Any) -> Any:
            solves.append((solver, args, kwargs))
            return solver(*args, **kwargs)

        return solve

    original = method.step
    from amex.plan.optimizer import compiled_loop, loop_calls
    from amex.plan.optimizer.assembly import BOUND

    costs = getattr(method, "costs", None)
    compiled = compiled_loop.ENABLED and BOUND and hasattr(method, "assembly")
    compiled = compiled and costs is not None and costs.final_velocity_space != "tcp"

    def timed(obs: Any) -> Any:
        solves.clear()
        cpu = time.thread_time_ns()
        out = original(obs)
        result.recorded_cpu.append((time.thread_time_ns() - cpu) * 1e-9)
        counted.append(method.status.iterations)
        calls: list[Call] = []
        iterations = 0
        with _recording(calls), _unfused():
            for solver, args, kwargs in solves:
                iterations += solver(*args, **kwargs).iterations
        if compiled:
            calls = _as_compiled(calls, method.assembly)  # type: ignore[attr-defined]
        floor_cpu, floor_wall = _replay(calls) if calls else (0.0, 0.0)
        result.floor_cpu.append(floor_cpu)
        result.floor_wall.append(floor_wall)
        result.iterations.append(iterations)
        return out

    loop_solve = loop_calls.ReplanLoop.solve

    def replanned(loop: Any, x: Any, frames: Any, first: int, *arrays: Any) -> Any:
        """CR's usual step (one compiled call): recorded as the same solve_trajectory call."""
        out = loop_solve(loop, x, frames, first, *arrays)
        if out is not None:
            q_start, v_start, goal_pos, goal_axis, obstacles, radii = arrays
            steps = x.shape[0]
            problem = optimizer.TrajectoryProblem(
                q_start, v_start, steps, loop.dt, goal_pos, goal_axis, obstacles, radii,
                loop.costs,
            )  # fmt: skip
            iterations, tolerance, damping = loop.settings[:3]
            kwargs = {
                "q_init": np.concatenate((q_start[None], x)),
                "max_iterations": iterations,
                "tolerance": tolerance,
                "damping": damping,
                "init_frames": None if frames is None else frames.take(slice(first, first + steps)),
                "assembly": loop.assembly,
                "compiled": True,
            }
            solves.append((solvers["solve_trajectory"], (method.robot, problem), kwargs))
        return out

    method.step = timed  # type: ignore[method-assign]
    try:
        loop_calls.ReplanLoop.solve = replanned  # type: ignore[method-assign,assignment]
        for name in solvers:
            setattr(optimizer, name, captured(name))
        _episode(run, task, env, method)
    finally:
        loop_calls.ReplanLoop.solve = loop_solve  # type: ignore[method-assign]
        for name, solver in solvers.items():
            setattr(optimizer, name, solver)
    return counted


def _timed_episode(
    run: Any, task: int, env: int, replan_loop: bool = True
) -> tuple[list[float], list[float], list[int]]:
    """Environment ``env`` on a fresh CR, each step timed alone: thread CPU, wall [s], iterations.

    ``replan_loop=False``: every solve through ``solve_trajectory`` (``CR.replan_loop = None``).
    """
    context = run.context
    method = run.method(context.plan, run.params, run.outer_dt, context.robot)
    if not replan_loop:
        method.replan_loop = None
    step = method.step
    cpus: list[float] = []
    walls: list[float] = []
    iterations: list[int] = []

    def timed(obs: Any) -> Any:
        tic, cpu = time.perf_counter_ns(), time.thread_time_ns()
        out = step(obs)
        cpus.append((time.thread_time_ns() - cpu) * 1e-9)
        walls.append((time.perf_counter_ns() - tic) * 1e-9)
        iterations.append(method.status.iterations)
        return out

    method.step = timed
    _episode(run, task, env, method)
    return cpus, walls, iterations


def path_times(
    task: int, envs: range = range(1), overrides: Sequence[str] = ()
) -> tuple[np.ndarray, np.ndarray]:
    """CR's step on its one-call path and on ``solve_trajectory``'s, step by step [s].

    Each environment runs twice, alternating: CR as it runs (its usual step one
    :class:`~amex.plan.optimizer.loop_calls.ReplanLoop` call) and CR with that path off (every
    solve through ``solve_trajectory``). The two see the same observations (the same numbers),
    so step i of one is step i of the other. Returns their thread CPU times, shape (steps,) each.
    """
    run = _cr_setup(task, overrides)
    times: tuple[list[float], list[float]] = ([], [])
    for env in envs:
        for one_call, store in ((True, times[0]), (False, times[1])):
            store.extend(_timed_episode(run, task, env, replan_loop=one_call)[0])
    return np.array(times[0]), np.array(times[1])


def _cr_setup(task: int, overrides: Sequence[str]) -> Any:
    """The run's set-up of CR on ``task`` (:func:`amex.experiment.runner.setup`)."""
    from amex.app.compose import load_config
    from amex.experiment.runner import prepare, setup

    config = load_config([*overrides, "method=cr", f"task={task}"])
    return setup(config, prepare(config))


def _episode(run: Any, task: int, env: int, method: Any) -> None:
    """Environment ``env`` of ``task`` (the run's seed) executed with ``method``."""
    from amex.sim.episode import run_episode
    from amex.sim.scenario import make_scenario

    context = run.context
    scenario = make_scenario(
        run.scene, task, run.seed, env, context.plan.y[0, :3], context.plan.duration
    )
    result = run_episode(context.robot, method, scenario, run.gains, run.loop)
    if result.failure.startswith("method:"):  # the episode's record of an error in the step
        raise RuntimeError(f"task {task}, environment {env}: {result.failure}")


def _us(values: Sequence[float] | np.ndarray, q: float) -> float:
    return float(np.percentile(values, q)) * 1e6


def main(argv: list[str] | None = None) -> None:
    """Print CR's step and floor, median and p95, per task."""
    parser = OneLineParser(prog="bench_cr", description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, nargs="*", default=[1, 2, 3, 4], choices=range(1, 5))
    parser.add_argument("--episodes", type=int, default=2, help="environments per task")
    parser.add_argument("--original", action="store_true", help="the authors' CR (Newton)")
    parser.add_argument(
        "--paths", action="store_true", help="CR's one-call step against solve_trajectory's"
    )
    args = parser.parse_args(argv)
    overrides = ("experiment=original",) if args.original else ()
    if args.paths:
        print("task  steps | one call CPU med | solve_trajectory CPU med | paired difference med")
        for task in args.tasks:
            one, solver = path_times(task, range(args.episodes), overrides)
            print(
                f"{task:4d} {len(one):6d} | {_us(one, 50):13.1f} us | {_us(solver, 50):21.1f} us |"
                f" {_us(solver - one, 50):18.1f} us"
            )
        return
    print(
        "task  steps  iters | step CPU med   p95 | floor CPU med   p95 | ratio med  p95"
        " | step wall med   p95 | floor wall med"
    )
    for task in args.tasks:
        r = cr_floor(task, range(args.episodes), overrides)
        solving = [i for i, it in enumerate(r.iterations) if it > 0]
        sc = [r.step_cpu[i] for i in solving]
        fc = [r.floor_cpu[i] for i in solving]
        ratios = [s / f for s, f in zip(sc, fc, strict=True)]
        sw = [r.step_wall[i] for i in solving]
        fw = [r.floor_wall[i] for i in solving]
        print(
            f"{task:4d} {len(solving):6d} {np.mean([r.iterations[i] for i in solving]):6.2f} |"
            f" {_us(sc, 50):9.1f} {_us(sc, 95):7.1f} | {_us(fc, 50):9.1f} {_us(fc, 95):7.1f} |"
            f" {_us(sc, 50) / _us(fc, 50):6.2f} {_us(sc, 95) / _us(fc, 95):5.2f} |"
            f" {_us(sw, 50):9.1f} {_us(sw, 95):7.1f} | {_us(fw, 50):9.1f}"
            f"   (per-step ratio median {np.median(ratios):.2f};"
            f" step after a recording {_us([r.recorded_cpu[i] for i in solving], 50):.1f})"
        )


if __name__ == "__main__":
    main()
