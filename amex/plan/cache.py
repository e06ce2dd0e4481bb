"""Compute the reference plan once per configuration and machine kernel, and keep it on disk.

The cache key is a SHA-256 of everything the plan depends on (:func:`plan_spec`): the robot (its
cleaned description, :attr:`~amex.robot.RobotModel.fingerprint`), the start configuration, the
goal, the plan settings, :data:`PLAN_FORMAT` (bumped when the optimizer's mathematics or the
file's layout change) and the BLAS kernel that solves it (:func:`blas_kernel`): the plan's last
bits follow the kernel (docs/reproducibility.md), so a cache shared by machines of different
kernels holds one plan per kernel, and every machine uses the plan it would have solved itself.

Files are written atomically (:func:`amex.core.durable.replace_durably`), so parallel workers can
share the cache. Each file carries its key and the specification it was solved for, and is used
only if both are this configuration's, it holds a finite plan of the configured shape, sample
period and start, its task-space image ``y`` is the kinematics of its ``q``, and its end is where
the solver puts it for this goal: one more Gauss-Newton step would move it by less than
:data:`END_TOLERANCE` (:func:`end_step`; the final costs are soft, so a solved plan's end misses
the goal by what its weights allow: 4e-5 m by default, cm for a short plan). Anything else (a
truncated, garbled or renamed file, a plan of another configuration or kernel) is ignored with
one warning saying why, solved again and replaced: never used. A cache that cannot be written
(read-only, or its path is a file) costs one warning and a solve per run, never the run.
"""

from __future__ import annotations

import ctypes
import hashlib
import io
import json
import logging
import math
import os
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from scipy.linalg import LinAlgError, solveh_banded
from scipy.linalg.lapack import dpbsv

from amex.core.durable import replace_durably
from amex.core.errors import WriteError
from amex.core.paths import cache_dir
from amex.plan.reference import PlanConfig, ReferencePlan
from amex.robot import RobotModel
from amex.robot.geometry import joint_metric

if TYPE_CHECKING:  # the optimizer's compiled kernels load with it, only where a plan is solved
    from amex.plan.optimizer import TrajectoryCosts, TrajectoryProblem

PLAN_FORMAT = 2  # 2: the file carries its key, specification and goal; the kernel is in the key
#: How far one more Gauss-Newton step may move a usable plan's end [m] (TCP) and [-] (z-axis)
#: (:func:`end_step`): 5x the most measured at solved plans, so a plan solved for a goal more
#: than about 0.2 mm away is refused.
END_TOLERANCE = 2e-4
_STEP_DAMPING = 1e-3  # the solvers' smallest Levenberg term

log = logging.getLogger(__name__)


def _openblas_libraries() -> list[str]:
    """Paths of the OpenBLAS libraries loaded in this process (Linux: ``/proc/self/maps``)."""
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line.lower()}
    except OSError:
        return []
    return sorted(p for p in paths if "openblas" in os.path.basename(p).lower())


def _openblas_core(path: str) -> str:
    """``"<core> (<build>)"`` of one OpenBLAS library, or "" if it does not say."""
    try:
        lib = ctypes.CDLL(path)
    except OSError:
        return ""
    for prefix in ("scipy_openblas_", "openblas_"):
        for suffix in ("64_", ""):
            core = getattr(lib, f"{prefix}get_corename{suffix}", None)
            build = getattr(lib, f"{prefix}get_config{suffix}", None)
            if core is not None and build is not None:
                core.restype = build.restype = ctypes.c_char_p
                return f"{core().decode()} ({' '.join(build().decode().split())})"
    return ""


def _probe() -> str:
    """Digest of the bits of a few fixed BLAS and LAPACK products (numpy's and scipy's)."""
    rng = np.random.default_rng(0)
    a = rng.standard_normal((37, 37))
    b = rng.standard_normal((37, 5))
    spd = a @ a.T + 37.0 * np.eye(37)
    band = np.zeros((15, 64))
    band[0] = 30.0
    band[1:] = 0.5 * rng.standard_normal((14, 64))
    _, x, _ = dpbsv(band, rng.standard_normal((64, 2)), lower=1)
    parts = (spd @ b, np.linalg.solve(spd, b), x, a @ a[0])
    return hashlib.sha256(b"".join(p.tobytes() for p in parts)).hexdigest()[:16]


@cache
def blas_kernel() -> dict[str, Any]:
    """What decides the reference plan's last bits on this machine: the BLAS kernel.

    ``cores``: the core type and build of every OpenBLAS library loaded (numpy's and scipy's
    each bring one; ``OPENBLAS_CORETYPE`` or the CPU picks the core); ``probe``: a digest of
    fixed products computed through them, which tells kernels apart where the library cannot
    be asked (another BLAS, another OS). Computed once per process.
    """
    cores = [core for core in map(_openblas_core, _openblas_libraries()) if core]
    return {"cores": sorted(cores), "probe": _probe()}


def plan_spec(robot: RobotModel, config: PlanConfig, goal_pos, goal_axis) -> dict[str, Any]:
    """Everything the reference plan depends on (the cache key is its digest)."""
    return {
        "format": PLAN_FORMAT,
        "robot": robot.fingerprint,
        "q0": [float(x) for x in robot.q0],
        "goal_pos": [float(x) for x in goal_pos],
        "goal_axis": [float(x) for x in goal_axis],
        "plan": {k: getattr(config, k) for k in sorted(vars(config))},
        "blas": blas_kernel(),
    }


def _spec_text(spec: dict[str, Any]) -> str:
    return json.dumps(spec, sort_keys=True)


def plan_key(robot: RobotModel, config: PlanConfig, goal_pos, goal_axis) -> str:
    """Hex digest identifying the plan for this robot, start, goal, settings and BLAS kernel."""
    text = _spec_text(plan_spec(robot, config, goal_pos, goal_axis))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def reference_costs(robot: RobotModel, config: PlanConfig) -> TrajectoryCosts:
    """The reference problem's cost terms (ConfigError for a setting they cannot take)."""
    from amex.plan.problem import TrajectoryCosts

    metric = joint_metric(config.metric, robot.nv)
    return TrajectoryCosts.from_weights(config, metric, config.final_velocity_space)


def reference_problem(
    robot: RobotModel, config: PlanConfig, goal_pos: np.ndarray, goal_axis: np.ndarray
) -> TrajectoryProblem:
    """The reference problem: no obstacles, start at rest in ``robot.q0`` (pure)."""
    from amex.plan.problem import TrajectoryProblem

    return TrajectoryProblem(
        q_start=robot.q0.copy(),
        v_start=np.zeros(robot.nv),
        steps=config.steps,
        dt=config.dt,
        goal_pos=np.asarray(goal_pos, dtype=float),
        goal_axis=np.asarray(goal_axis, dtype=float),
        obstacles=np.zeros((0, 3)),
        obstacle_radii=np.zeros(0),
        costs=reference_costs(robot, config),
    )


def solve_reference(
    robot: RobotModel, config: PlanConfig, goal_pos: np.ndarray, goal_axis: np.ndarray
) -> ReferencePlan:
    """Solve the reference problem (:func:`reference_problem`) from scratch."""
    from amex.plan.optimizer import solve_trajectory, solve_trajectory_newton

    problem = reference_problem(robot, config, goal_pos, goal_axis)
    if config.solver == "newton":
        solution = solve_trajectory_newton(robot, problem, max_iterations=config.max_iterations)
    else:
        solution = solve_trajectory(robot, problem, max_iterations=config.max_iterations)
    y = np.array([robot.task_position(q) for q in solution.q])
    return ReferencePlan(q=solution.q, y=y, dt=config.dt, metric=problem.costs.metric)


class CacheRead(NamedTuple):
    """A cache file's plan, or None and why it is not used ("" for a missing file).

    ``checked_now``: the plan passed the end check in this read (the file had no digest of an
    earlier one, :func:`_checked_digest`).
    """

    plan: ReferencePlan | None
    problem: str
    checked_now: bool = False


def end_step(
    robot: RobotModel, config: PlanConfig, q: np.ndarray, goal_pos, goal_axis
) -> tuple[float, float]:
    """How far one Gauss-Newton step of the reference problem would move the plan ``q``'s end.

    The step the solvers take (normal equations at ``q``, Levenberg term at the solvers' floor
    1e-3); returns the change of the end's TCP position [m] and z-axis [-]. At a solved plan it
    is small (measured <= 4e-5 m, also for short plans and weak final weights that end cm from
    the goal); for a plan of a goal moved by d it is about d.
    """
    from amex.plan.optimizer import build_normal_equations

    equations = build_normal_equations(
        robot, reference_problem(robot, config, goal_pos, goal_axis), q
    )
    band = np.array(equations.hessian)
    band[0] += _STEP_DAMPING
    try:
        step = solveh_banded(band, -equations.gradient, lower=True, check_finite=False)
    except (LinAlgError, ValueError):
        return math.inf, math.inf
    end = q[-1] + step.reshape(-1, robot.nv)[-1]
    moved = robot.task_position(end) - robot.task_position(q[-1])
    return float(np.linalg.norm(moved[:3])), float(np.linalg.norm(moved[3:]))


def _end_problem(
    robot: RobotModel, config: PlanConfig, plan: ReferencePlan, goal_pos, goal_axis
) -> str:
    """Why ``plan`` is not this configuration's solution at its end ("" if it is)."""
    position, axis = end_step(robot, config, plan.q, goal_pos, goal_axis)
    if position <= END_TOLERANCE and axis <= END_TOLERANCE:
        return ""
    return (
        f"its end is not where the solver puts it for this goal: one more step moves it "
        f"{position:.3g} m and {axis:.3g} in axis (allowed: {END_TOLERANCE:g})"
    )


def _differences(stored: str, wanted: str) -> str:
    """Which parts of the specification differ between a file's and this configuration's."""
    try:
        theirs = json.loads(stored)
    except ValueError:
        return "no readable specification"
    mine = json.loads(wanted)
    if not isinstance(theirs, dict):
        return "no readable specification"
    differ = sorted(k for k in mine.keys() | theirs.keys() if theirs.get(k) != mine.get(k))
    return f"its {', '.join(differ)} differ" if differ else "its key differs"


def read_cached(
    path: Path, robot: RobotModel, config: PlanConfig, goal_pos, goal_axis
) -> CacheRead:
    """The plan stored at ``path`` if it fits (module notes), else None and the reason."""
    goal_pos = np.asarray(goal_pos, dtype=float)
    goal_axis = np.asarray(goal_axis, dtype=float)
    if not os.path.lexists(path):
        return CacheRead(None, "")
    spec = _spec_text(plan_spec(robot, config, goal_pos, goal_axis))
    key = hashlib.sha256(spec.encode()).hexdigest()[:20]
    try:
        with np.load(path, allow_pickle=False) as f:
            q = np.array(f["q"], dtype=float)
            y = np.array(f["y"], dtype=float)
            dt = float(f["dt"])
            stored_key, stored_spec = str(f["key"]), str(f["spec"])
            checked = str(f["checked"]) if "checked" in f.files else ""
    except Exception as e:  # missing, truncated, garbled, not an npz: numpy raises many types
        reason = str(e).splitlines()[0][:120] if str(e) else ""
        return CacheRead(None, f"unreadable: {type(e).__name__} {reason}".rstrip())
    n = config.steps + 1
    if stored_key != key or stored_spec != spec:
        return CacheRead(
            None, f"solved for another configuration ({_differences(stored_spec, spec)})"
        )
    if not (q.shape == (n, robot.nv) and y.shape == (n, 6)):
        return CacheRead(None, f"a plan of shape {q.shape}/{y.shape}, expected ({n}, {robot.nv})")
    if not math.isclose(dt, config.dt, rel_tol=1e-12):
        return CacheRead(None, f"sample period {dt}, expected {config.dt}")
    if not (np.isfinite(q).all() and np.isfinite(y).all()):
        return CacheRead(None, "non-finite values")
    if not np.allclose(q[0], robot.q0, rtol=0.0, atol=1e-9):
        return CacheRead(None, "another start configuration")
    plan = ReferencePlan(q=q, y=y, dt=config.dt, metric=joint_metric(config.metric, robot.nv))
    if checked and checked == _checked_digest(key, q, y, dt):
        return CacheRead(plan, "")  # written by reference_plan, y from q, after its end check
    image = np.array([robot.task_position(qk) for qk in q])
    if not np.allclose(y, image, rtol=0.0, atol=1e-9):
        return CacheRead(None, "its task-space image is not the kinematics of its joints")
    problem = _end_problem(robot, config, plan, goal_pos, goal_axis)
    return CacheRead(None, problem) if problem else CacheRead(plan, "", checked_now=True)


def _checked_digest(key: str, q: np.ndarray, y: np.ndarray, dt: float) -> str:
    """What a file that passed the end check carries (``checked``): a digest of its contents.

    :func:`reference_plan` stores it beside a plan it solved and checked, so a reader skips
    the image and end checks (a forward kinematics per knot and a Gauss-Newton linearization of
    the whole plan, ~0.1-0.2 s of every run's start-up) for exactly those contents; a file
    without it, or whose plan, key or sample period changed since, is checked again.
    """
    digest = hashlib.sha256(key.encode())
    for part in (np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(y, dtype=float)):
        digest.update(part.tobytes())
    digest.update(np.float64(dt).tobytes())
    return digest.hexdigest()


def load_cached(
    path: Path, robot: RobotModel, config: PlanConfig, goal_pos, goal_axis
) -> ReferencePlan | None:
    """The plan stored at ``path`` if it fits (:func:`read_cached`), else None."""
    return read_cached(path, robot, config, goal_pos, goal_axis).plan


def store(path: Path, plan: ReferencePlan, spec: dict[str, Any], checked: bool = False) -> bool:
    """Write ``plan`` with its ``spec`` (:func:`plan_spec`) to ``path`` atomically.

    ``checked``: the plan passed the end check for ``spec`` (:func:`reference_plan`); the file
    then carries the digest that lets readers skip it (:func:`_checked_digest`).

    Returns:
        False (and one warning) if the cache is unwritable.
    """
    text = _spec_text(spec)
    key = hashlib.sha256(text.encode()).hexdigest()[:20]
    buffer = io.BytesIO()
    fields: dict[str, Any] = {"q": plan.q, "y": plan.y, "dt": plan.dt, "key": key, "spec": text}
    if checked:
        fields["checked"] = _checked_digest(key, plan.q, plan.y, float(plan.dt))
    np.savez(buffer, **fields)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        replace_durably(path, buffer.getvalue())
    except (OSError, WriteError) as e:
        reason = e.reason if isinstance(e, WriteError) else (e.strerror or str(e))
        log.warning(
            "plan cache %s not written (%s): the plan is solved again by every run; "
            "set AMEX_CACHE_DIR to a writable directory",
            path.parent,
            reason,
        )
        return False
    return True


def reference_plan(
    robot: RobotModel,
    config: PlanConfig,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    directory: Path | None = None,
) -> ReferencePlan:
    """The reference plan: from the disk cache when a fitting one is there, else solved, stored.

    A cache file that does not fit is ignored with a warning naming it and why. A solved plan
    that fails the end check (the solver stopped far from converged) is used, with a warning,
    but not stored: the cache never holds a plan its reader would refuse.
    """
    directory = cache_dir() / "plans" if directory is None else directory
    spec = plan_spec(robot, config, goal_pos, goal_axis)
    path = directory / f"plan_{plan_key(robot, config, goal_pos, goal_axis)}.npz"
    cached = read_cached(path, robot, config, goal_pos, goal_axis)
    if cached.plan is not None:
        if cached.checked_now:  # a file of an earlier version: its check is not repeated
            store(path, cached.plan, spec, checked=True)
        return cached.plan
    if cached.problem:
        log.warning("plan cache file %s not used (%s): solved again", path, cached.problem)
    plan = solve_reference(robot, config, goal_pos, goal_axis)
    problem = _end_problem(robot, config, plan, goal_pos, goal_axis)
    if problem:
        log.warning("the solved reference plan misses its goal: %s; not cached", problem)
    else:
        store(path, plan, spec, checked=True)
    return plan
