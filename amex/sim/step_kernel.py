"""The episode loop's own arithmetic and the controller's solve as one compiled call per step.

:func:`episode_step` does, at inner step ``k``, what :func:`amex.sim.episode._run` did in Python
and what :meth:`~amex.control.osc.OperationalSpaceController.accelerations` did in two calls:

* ``MEASURE``: the joint angles into the history, the TCP path's length, the goal of the moving
  goal (``Scenario.goal_at``), the TCP-goal distance of the stop rule (the previous step's TCP
  under ``state_lag``), and whether the episode stops here (the stop radius or its last step);
* ``CONTROL``: the collision task's ``(phi, J)`` from coal's results
  (:mod:`amex.control.collision_kernels`), the normal equations of Eq. 4-6 and their Cholesky
  solve (:func:`amex.control.kernels.osc_accelerations`), and, in a kinematic simulation, the
  explicit Euler step of ``q`` and ``q_dot``.

Every array it reads or writes lives at a fixed address for the episode: MuJoCo's ``qpos`` and
``qvel``, Pinocchio's TCP placement ``oMf`` and joint Jacobians ``J``, coal's distance results,
the controller's work space and the loop's own state. A compiled call unboxes each array argument
(~0.1-0.4 us each), so they travel as one int64 vector
:data:`~amex.sim.step_layout.ADDRESSES` long whose entries are those addresses and the sizes (the
slots of :mod:`amex.sim.step_layout`); :class:`amex.sim.inner_step.StepMemory` builds it and
holds the arrays alive. Only the step's new Jacobian and drift (Pinocchio returns new
arrays) are arguments of their own.

Bit for bit: the same IEEE operations in the same order as the Python and numpy code they replace
(no ``fastmath``). Python's ``x ** 2`` on floats is the C library's ``pow(x, 2.0)``, which rounds
differently from ``x * x`` in about one case in a thousand, so the squares here call ``pow`` with
an exponent read at run time (LLVM would turn a constant 2.0 into a product).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from amex.control import collision_kernels, kernels
from amex.sim.step_layout import (  # the slots, flags and sizes (module notes there)
    AXIS_X,
    AXIS_Y,
    AXIS_Z,
    CENTERS,
    COL,
    COLLISION,
    CONSTANTS,
    CONSTANTS_SIZE,
    CONTROL,
    DISTANCE,
    DT,
    GO_ON,
    GOAL_MOVES_UNTIL,
    GOAL_START,
    GOAL_STOP_TIME,
    GOAL_VELOCITY,
    GOAL_X,
    GOAL_Y,
    GOAL_Z,
    HAS_PREV,
    HINGE,
    HISTORY,
    INFO,
    JOINT_JACOBIANS,
    KINEMATIC,
    LAG,
    LOOP,
    LOOP_SIZE,
    MARGIN,
    MEASURE,
    N_ARM,
    N_GEOMS,
    N_JOINTS,
    N_OBSTACLES,
    N_PAIRS,
    N_STEPS,
    NO_COLLISION,
    PAIR_ARM,
    PAIR_OBSTACLE,
    PARAMS,
    PATH_LENGTH,
    PLACEMENT_STRIDE,
    PLACEMENTS,
    PREV_X,
    PREV_Y,
    PREV_Z,
    QPOS,
    QVEL,
    REACH,
    SOLVER_FAILED,
    SPEED_LIMIT,
    SQUARE,
    STOP,
    STOP_RADIUS,
    SUPPORT,
    TABLE,
    TABLE_STRIDE,
    TARGETS,
    TCP_POSE,
    TORQUE_HIGH,
    TORQUE_LOW,
    TORQUE_OUT,
    WORKSPACE,
)


@intrinsic
def _float64_at(typingctx, address):  # type: ignore[no-untyped-def]
    """The int64 ``address`` as a float64 pointer (for ``numba.carray``)."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return sig, codegen


@intrinsic
def _int64_at(typingctx, address):  # type: ignore[no-untyped-def]
    """The int64 ``address`` as an int64 pointer (for ``numba.carray``)."""
    sig = types.CPointer(types.int64)(types.int64)

    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))

    return sig, codegen


@numba.njit(cache=True)
def _floats(mem: np.ndarray, slot: int, size: int) -> np.ndarray:
    """The float64 array of ``size`` at the address in ``mem[slot]``."""
    return numba.carray(_float64_at(mem[slot]), (size,))  # type: ignore[call-arg]


@numba.njit(cache=True)
def _matrix(mem: np.ndarray, slot: int, rows: int, cols: int) -> np.ndarray:
    """The C-ordered float64 matrix (rows, cols) at the address in ``mem[slot]``."""
    return numba.carray(_float64_at(mem[slot]), (rows, cols))  # type: ignore[call-arg]


@numba.njit(cache=True)
def _ints(mem: np.ndarray, slot: int, size: int) -> np.ndarray:
    """The int64 array of ``size`` at the address in ``mem[slot]``."""
    return numba.carray(_int64_at(mem[slot]), (size,))  # type: ignore[call-arg]


@numba.njit(cache=True)
def _rows(mem: np.ndarray, slot: int, rows: int, stride: int, width: int) -> np.ndarray:
    """``rows`` rows of ``width`` float64, ``stride`` doubles apart, from ``mem[slot]``.

    (The rows' padding beyond ``width`` is never read.)
    """
    return _matrix(mem, slot, rows, stride)[:, :width]


@numba.njit(cache=True)
def _measure(mem: np.ndarray, k: int, qpos: np.ndarray, tcp: np.ndarray) -> int:
    """The MEASURE phase (module notes); the loop state in ``mem[LOOP]``."""
    n = mem[N_JOINTS]
    loop = _floats(mem, LOOP, LOOP_SIZE)
    const = _floats(mem, CONSTANTS, CONSTANTS_SIZE)
    history = _matrix(mem, HISTORY, mem[N_STEPS] + 1, n)
    for i in range(n):
        history[k, i] = qpos[i]
    two = const[SQUARE]
    tx, ty, tz = tcp[0, 3], tcp[1, 3], tcp[2, 3]
    px, py, pz = tx, ty, tz  # the TCP the stop rule sees
    if loop[HAS_PREV] != 0.0:  # the TCP path's length, step by step
        ox, oy, oz = loop[PREV_X], loop[PREV_Y], loop[PREV_Z]
        loop[PATH_LENGTH] += math.sqrt(
            math.pow(tx - ox, two) + math.pow(ty - oy, two) + math.pow(tz - oz, two)
        )
        if mem[LAG] != 0:
            px, py, pz = ox, oy, oz
    loop[PREV_X], loop[PREV_Y], loop[PREV_Z], loop[HAS_PREV] = tx, ty, tz, 1.0
    loop[AXIS_X], loop[AXIS_Y], loop[AXIS_Z] = tcp[0, 2], tcp[1, 2], tcp[2, 2]
    t = k * const[DT]
    if t <= const[GOAL_MOVES_UNTIL]:  # Scenario.goal_at
        s = min(t, const[GOAL_STOP_TIME])
        for i in range(3):
            loop[GOAL_X + i] = const[GOAL_START + i] + const[GOAL_VELOCITY + i] * s
    gx, gy, gz = loop[GOAL_X], loop[GOAL_Y], loop[GOAL_Z]
    d = math.sqrt(math.pow(px - gx, two) + math.pow(py - gy, two) + math.pow(pz - gz, two))
    loop[DISTANCE] = d
    if d <= const[STOP_RADIUS] or k == mem[N_STEPS]:
        return STOP
    return GO_ON


@numba.njit(cache=True)
def _collision_terms(mem: np.ndarray, col: np.ndarray, n: int) -> None:
    """The held command's collision task into ``col`` (``col[0] = 0``: off)."""
    kind = mem[COLLISION]
    if kind == NO_COLLISION:
        col[0] = 0.0
        return
    n_pairs = mem[N_PAIRS]
    table = _rows(mem, TABLE, n_pairs, mem[TABLE_STRIDE], 10)
    J_world = _matrix(mem, JOINT_JACOBIANS, n, 6).T  # column major (6, n)
    support = _matrix(mem, SUPPORT, n_pairs, n)
    pair_obstacle = _ints(mem, PAIR_OBSTACLE, n_pairs)
    centers = _matrix(mem, CENTERS, mem[N_OBSTACLES], 3)
    margin = _floats(mem, CONSTANTS, CONSTANTS_SIZE)[MARGIN]
    if kind == HINGE:
        collision_kernels.hinge_terms(col, table, J_world, support, pair_obstacle, centers, margin)
        return
    placements = _rows(mem, PLACEMENTS, mem[N_GEOMS], mem[PLACEMENT_STRIDE], 12)
    pair_arm = _ints(mem, PAIR_ARM, n_pairs)
    reach = _floats(mem, REACH, mem[N_ARM])
    collision_kernels.proxy_terms(
        col, table, placements, J_world, support, pair_obstacle, pair_arm, centers, reach, margin
    )


@numba.njit(cache=True)
def _control(
    mem: np.ndarray,
    J: np.ndarray,
    drift: np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    tcp: np.ndarray,
) -> int:
    """The CONTROL phase (module notes): q_ddot* into the controller's work space."""
    n = mem[N_JOINTS]
    ws = _matrix(mem, WORKSPACE, 2 * n + 2, n)
    targets = _floats(mem, TARGETS, 14 + 2 * n)  # kernels.targets_size
    col = _floats(mem, COL, 1 + n)
    params = _floats(mem, PARAMS, kernels.HDIAG + 2 * n)
    _collision_terms(mem, col, n)
    info = kernels.osc_accelerations(ws, J, qvel, qpos, tcp, drift, targets, col, params)
    if info != 0:
        _floats(mem, LOOP, LOOP_SIZE)[INFO] = info
        return SOLVER_FAILED
    if mem[KINEMATIC] != 0:
        kernels.euler_inplace(qpos, qvel, ws[n + 1], _floats(mem, CONSTANTS, CONSTANTS_SIZE)[DT])
    return GO_ON


@numba.njit(cache=True)
def episode_step(mem: np.ndarray, J: np.ndarray, drift: np.ndarray, k: int, phase: int) -> int:
    """The phases ``phase`` (``MEASURE``, ``CONTROL`` or ``BOTH``) of inner step ``k``.

    Args:
        mem: the address vector (module notes), length :data:`~amex.sim.step_layout.ADDRESSES`.
        J: TCP Jacobian (6, n), LOCAL_WORLD_ALIGNED (``pin.getFrameJacobian``); read by CONTROL.
        drift: TCP classical acceleration at q_ddot = 0 (6,); read by CONTROL.
        k: the step.
        phase: the phases to run, in the order MEASURE, CONTROL.

    Returns:
        ``STOP`` where MEASURE ends the episode (CONTROL then does not run), ``SOLVER_FAILED``
        where the normal equations are not positive definite (their ``info`` in the loop state),
        else ``GO_ON``.
    """
    n = mem[N_JOINTS]
    qpos = _floats(mem, QPOS, n)
    qvel = _floats(mem, QVEL, n)
    tcp = _matrix(mem, TCP_POSE, 4, 3).T  # (3, 4): rotation (column major), then position
    if phase & MEASURE and _measure(mem, k, qpos, tcp) == STOP:
        return STOP
    if phase & CONTROL:
        return _control(mem, J, drift, qpos, qvel, tcp)
    return GO_ON


@numba.njit(cache=True)
def clip_torque(mem: np.ndarray, tau: np.ndarray) -> None:
    """The torque ``tau`` clipped to the limits into the simulator's applied forces (clip_into)."""
    n = mem[N_JOINTS]
    out = _floats(mem, TORQUE_OUT, n)
    kernels.clip_into(out, tau, _floats(mem, TORQUE_LOW, n), _floats(mem, TORQUE_HIGH, n))


@numba.njit(cache=True)
def speeds_within_limit(mem: np.ndarray) -> bool:
    """Whether every ``|q_dot_i| <= limit_i`` (False for a NaN), as ``check_simulation`` tests."""
    n = mem[N_JOINTS]
    qvel, limit = _floats(mem, QVEL, n), _floats(mem, SPEED_LIMIT, n)
    for i in range(n):  # noqa: SIM110 (a loop, which Numba compiles without a generator)
        if not abs(qvel[i]) <= limit[i]:
            return False
    return True
