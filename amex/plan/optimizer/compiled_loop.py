"""The whole Levenberg-Gauss-Newton solve in one compiled call (CR's every outer step, issue #29).

:func:`~amex.plan.optimizer.levenberg.solve_trajectory` on the compiled iteration
(:class:`~.assembly.CompiledSolve`) makes about 15 Python-level calls per iteration, each a few
microseconds of interpreter between compiled kernels; CR runs one to three iterations per outer
step, so that glue was a third of its step. :func:`levenberg_loop` runs the same iterations,
statement for statement (the same kernels in the same order: :mod:`.assembly_kernels`,
:mod:`.iteration_kernels`, :mod:`amex.plan.kinematics_kernels`, numpy's BLAS and SciPy's LAPACK
through :mod:`.blas`), inside one compiled function.

One thing differs: Pinocchio cannot be called from compiled code, so the TCP's placement and
frame Jacobian at the last knot (the final terms' kinematics, Section IV's final position and
axis costs) come from the batched frames (:func:`tcp_kinematics`: the same chain of joint
placements, the Jacobian's columns ``z_i x (p - p_i)`` and ``z_i``), which round differently
from Pinocchio's in the last bits. The solve's numbers then agree with the Pinocchio path's to
~1e-15 relative per evaluation, not bit for bit; whole episodes keep their success and final
times (docs/results/speed.md gives the measured differences). ``tests/plan/test_compiled_loop.py``
compares the two paths.

Its callers' side (the arguments put together, the answer turned into a solution or an error)
is :mod:`.loop_calls`.

Over the 80-line guide for a function on purpose: :func:`levenberg_loop` is
:func:`~.levenberg.solve_trajectory` written out, with :meth:`~.assembly.CompiledSolve.evaluate`
as :func:`_evaluate`, so that each reads beside its Python original.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from amex.plan.kinematics_kernels import (
    capsule_sphere_distances,
    forward_frames,
    near_pairs,
    pair_gradients,
)
from amex.plan.knots_kernels import midpoint_target
from amex.plan.optimizer.assembly_kernels import start_residuals, take_step, wake_pairs
from amex.plan.optimizer.blas import ddot
from amex.plan.optimizer.iteration_kernels import damped_solve, final_cost, final_products
from amex.plan.optimizer.residuals import GUARD

__all__ = ["ENABLED", "INITIAL_DAMPING", "levenberg_loop", "tcp_kinematics"]

#: Whether :func:`~.levenberg.solve_trajectory` runs :func:`levenberg_loop` where it can (the
#: tests and ``python -m amex.app.bench_cr`` switch it off to run the Python loop beside it).
ENABLED = True
#: Levenberg lambda of the first iteration (:func:`~.levenberg.solve_trajectory`, and here).
INITIAL_DAMPING = 1.0
#: :func:`levenberg_loop`'s outcomes (its first return value): solved, or the error.
SOLVED, BAD_START, BAD_TRIAL, NOT_DEFINITE, ILLEGAL = 0, 1, 2, 3, 4


@numba.njit(cache=True)
def tcp_kinematics(
    local: np.ndarray,
    parents: np.ndarray,
    q: np.ndarray,
    tcp_joint: int,
    tcp_point: np.ndarray,
    tcp_rotation: np.ndarray,
    tcp_support: np.ndarray,
    J: np.ndarray,
    rotation: np.ndarray,
    position: np.ndarray,
) -> None:
    """The TCP's world-aligned frame Jacobian ``J`` (6, n), ``rotation`` (3, 3), ``position`` (3,).

    What Pinocchio's ``computeJointJacobians``, ``updateFramePlacement`` and
    ``getFrameJacobian(..., LOCAL_WORLD_ALIGNED)`` give at one configuration ``q`` (n,), from the
    batched frames (:func:`~amex.plan.kinematics_kernels.forward_frames`, joint axes turned to
    z): the TCP point ``tcp_point`` and rotation ``tcp_rotation`` in its joint's turned frame;
    column i is ``(z_i x (p - p_i), z_i)`` for the joints in ``tcp_support`` (n,), else zero.
    """
    n = q.shape[0]
    njoints = local.shape[0]
    sin, cos = np.empty((n, 1)), np.empty((n, 1))
    for i in range(n):
        sin[i, 0], cos[i, 0] = math.sin(q[i]), math.cos(q[i])
    axes, pos = np.empty((njoints, 3, 3, 1)), np.empty((njoints, 3, 1))
    forward_frames(local, parents, sin, cos, axes, pos)
    j = tcp_joint
    for a in range(3):  # axes[j, b, a]: component a of the frame's column b
        position[a] = pos[j, a, 0] + (
            tcp_point[0] * axes[j, 0, a, 0]
            + tcp_point[1] * axes[j, 1, a, 0]
            + tcp_point[2] * axes[j, 2, a, 0]
        )
        for c in range(3):
            rotation[a, c] = (
                axes[j, 0, a, 0] * tcp_rotation[0, c]
                + axes[j, 1, a, 0] * tcp_rotation[1, c]
                + axes[j, 2, a, 0] * tcp_rotation[2, c]
            )
    for i in range(n):
        if not tcp_support[i]:
            for r in range(6):
                J[r, i] = 0.0
            continue
        z0, z1, z2 = axes[i + 1, 2, 0, 0], axes[i + 1, 2, 1, 0], axes[i + 1, 2, 2, 0]
        d0 = position[0] - pos[i + 1, 0, 0]
        d1 = position[1] - pos[i + 1, 1, 0]
        d2 = position[2] - pos[i + 1, 2, 0]
        J[0, i] = z1 * d2 - z2 * d1
        J[1, i] = z2 * d0 - z0 * d2
        J[2, i] = z0 * d1 - z1 * d0
        J[3, i], J[4, i], J[5, i] = z0, z1, z2


@numba.njit(cache=True)
def _evaluate(
    x: np.ndarray,
    r_acc: np.ndarray,
    v_last: np.ndarray,
    r_fin: np.ndarray,
    J_fin: np.ndarray,
    frames: tuple,  # type: ignore[type-arg]
    fixed: tuple,  # type: ignore[type-arg]
    problem: tuple,  # type: ignore[type-arg]
    robot: tuple,  # type: ignore[type-arg]
    known: tuple,  # type: ignore[type-arg]
    use_known: bool,
    reuse_dist: bool,
) -> tuple:  # type: ignore[type-arg]
    """:meth:`~.assembly.CompiledSolve.evaluate` at ``x`` with its residual buffers filled."""
    J, R, p, rows, Jz = frames
    goal_pos, goal_axis, obstacles, radii, collides = problem[2:]
    dt, w, margin, s_col = fixed[0], fixed[5], fixed[6], fixed[7]
    local, parents, tcp_joint, tcp_point, tcp_rot, tcp_support = robot[:6]
    cap_joint, cap_ends, cap_inv_len2, cap_radius = robot[6:10]
    T = x.shape[0]
    tcp_kinematics(local, parents, x[T - 1], tcp_joint, tcp_point, tcp_rot, tcp_support, J, R, p)
    cost = final_cost(J, R, p, v_last, goal_pos, goal_axis, w, dt, rows, Jz, r_fin, J_fin, r_acc)
    C, k = cap_joint.shape[0], radii.shape[0]
    if not collides:
        axes, pos = known[0][:, :, :, :0], known[1][:, :, :0]
        distance, offset = known[2][:, :, :0], known[3][:, :, :, :0]
        none = np.empty(0, dtype=np.int64)
        return cost, axes, pos, distance, offset, none, none, none, np.empty(0)
    if use_known:
        axes, pos = known[0], known[1]
    else:
        axes = np.empty((local.shape[0], 3, 3, T))
        pos = np.empty((local.shape[0], 3, T))
        qt = x.T
        forward_frames(local, parents, np.sin(qt), np.cos(qt), axes, pos)
    if use_known and reuse_dist:
        distance, offset = known[2], known[3]
    else:
        distance, offset = np.empty((C, k, T)), np.empty((C, k, 3, T))
        capsule_sphere_distances(
            axes,
            pos,
            cap_joint,
            cap_ends,
            cap_inv_len2,
            cap_radius,
            obstacles,
            radii,
            distance,
            offset,
        )
    scratch = np.empty((C, k, T))  # near_pairs' dense residuals, not read
    cap, obs, knot, r_near = near_pairs(distance, margin, GUARD, s_col, scratch)
    if knot.size:
        cost += ddot(r_near, r_near)
    return cost, axes, pos, distance, offset, cap, obs, knot, r_near


@numba.njit(cache=True)
def levenberg_loop(
    x0: np.ndarray,
    fixed: tuple,  # type: ignore[type-arg]
    problem: tuple,  # type: ignore[type-arg]
    robot: tuple,  # type: ignore[type-arg]
    known: tuple,  # type: ignore[type-arg]
    use_known: bool,
    reuse_dist: bool,
    settings: tuple,  # type: ignore[type-arg]
    band: np.ndarray,
    rhs: np.ndarray,
    target: tuple,  # type: ignore[type-arg]
) -> tuple:  # type: ignore[type-arg]
    """:func:`~.levenberg.solve_trajectory` from the free knots ``x0`` (T, n), T >= 2.

    Returns ``(outcome, value, q, cost, iterations, converged, axes, pos, distance, offset,
    q_mid, qd)``: ``outcome`` 0 (solved) or an error whose ``value`` is the non-finite cost or
    LAPACK's ``info``; ``q`` the solution with the start as row 0; the frames and distances at
    its free knots (empty without collision term); CR's joint target from ``q``
    (:func:`~amex.plan.knots_kernels.midpoint_target` at ``target = (stride, dt)``; empty for a
    stride of 0).
    """
    dt, s_acc, scale, metric, s_acc2, w, margin, s_col = fixed
    q_start, v_start, obstacles, collides = problem[0], problem[1], problem[4], problem[6]
    cap_support = robot[10]
    max_iterations, tolerance, damping, initial_damping = settings
    T, n = x0.shape
    m = 9 + n
    frames = (np.empty((6, n)), np.empty((3, 3)), np.empty(3), np.empty((3, n)), np.empty((3, n)))
    # two sets of trial buffers, taken in turn (never the set holding the current point)
    knots = np.empty((2, T, n))
    accs = np.empty((2, T, n))
    velocities = np.empty((2, n))
    fins = np.empty((2, m))
    jacs = np.empty((2, m, 2 * n))
    x = x0
    r_acc, v_last = np.empty((T, n)), np.empty(n)
    start_residuals(x, q_start, v_start, dt, s_acc, r_acc, v_last)
    r_fin, J_fin = np.empty(m), np.empty((m, 2 * n))
    point = _evaluate(
        x, r_acc, v_last, r_fin, J_fin, frames, fixed, problem, robot, known, use_known, reuse_dist
    )
    cost = point[0]
    outcome, value = (SOLVED, 0.0) if math.isfinite(cost) else (BAD_START, cost)
    lam = max(damping, initial_damping)
    converged, iterations = False, 0
    C, k = robot[6].shape[0], problem[5].shape[0]  # capsules, obstacles
    woken = np.zeros((C, k, T) if k > 0 else (0, 0, 0), dtype=np.bool_)
    current_set = -1  # the trial set holding the point (-1: x0)
    linearized = False
    JtJ, Jtr = np.empty((0, 0)), np.empty(0)
    J_col = np.empty((0, n))
    first = n * T - 2 * n
    while outcome == SOLVED and iterations < max_iterations and not converged:
        iterations += 1
        cap, obs, knot, r_near = point[5], point[6], point[7], point[8]
        if not linearized:  # CompiledSolve.linearize
            J_col = np.empty((0, n))
            if knot.size:
                J_col = np.empty((cap.shape[0], n))
                axis = point[1][:, 2]
                pair_gradients(
                    axis, point[2], point[4], obstacles, cap_support, cap, obs, knot, J_col
                )
                J_col *= -s_col / margin
            JtJ, Jtr = final_products(J_fin, r_fin)
            linearized = True
        info = damped_solve(
            band,
            rhs,
            scale,
            metric,
            JtJ,
            Jtr,
            first,
            r_acc,
            s_acc2,
            cap,
            obs,
            knot,
            J_col,
            r_near,
            woken,
            lam,
        )
        if info != 0:
            outcome, value = (NOT_DEFINITE if info > 0 else ILLEGAL), float(info)
            break
        s = 0 if current_set != 0 else 1
        small = take_step(
            x, rhs, q_start, v_start, dt, s_acc, tolerance, knots[s], accs[s], velocities[s]
        )
        trial = _evaluate(
            knots[s],
            accs[s],
            velocities[s],
            fins[s],
            jacs[s],
            frames,
            fixed,
            problem,
            robot,
            known,
            False,
            False,
        )
        new_cost = trial[0]
        if not math.isfinite(new_cost):
            outcome, value = BAD_TRIAL, new_cost
            break
        if new_cost <= cost:
            converged = small or cost - new_cost <= tolerance * cost
            point, cost, current_set, linearized = trial, new_cost, s, False
            x, r_acc, v_last, r_fin, J_fin = knots[s], accs[s], velocities[s], fins[s], jacs[s]
            lam = max(damping, lam / 10.0)
        else:
            converged = small
            woke = False
            if knot.size and collides:
                woke = wake_pairs(cap, obs, knot, r_near, trial[3], margin, s_col, woken)
            if not woke:
                lam *= 10.0
    q = np.empty((T + 1, n))
    q[0] = q_start
    q[1:] = x
    stride, target_dt = target
    q_mid, qd = np.empty(n if stride > 0.0 else 0), np.empty(n if stride > 0.0 else 0)
    if stride > 0.0:
        midpoint_target(q, stride, target_dt, q_mid, qd)
    axes, pos, distance, offset = point[1], point[2], point[3], point[4]
    return outcome, value, q, cost, iterations, converged, axes, pos, distance, offset, q_mid, qd
