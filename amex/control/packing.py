"""The operational-space controller's constants and held command, packed for its compiled kernels.

The controller's constants travel as one float64 vector at named offsets (:func:`pack_params`,
:func:`params_dtype`), the held command as another (:func:`pack_targets`), read by
:mod:`amex.control.kernels` and :mod:`amex.sim.step_kernel`. Apart from the compiled code so
that the controller packs them without importing Numba (:mod:`amex.core.compiled`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from amex.core.types import PD

_F8 = np.float64


#: The scalar fields of the controller's constants, in the order of :func:`params_dtype`; then
#: ``hdiag`` (n) and ``q_rest`` (n). The compiled kernels read the packed vector at these offsets.
PARAM_SCALARS = (
    "pos_kp",  # position task (Eq. 6, first row of Eq. 5)
    "pos_kd",
    "pos_weight",
    "axis_kp",  # axis task (second row)
    "axis_kd",
    "axis_weight",
    "damping_velocity",  # -weight * Kd of the damping task (times v)
    "damping_posture",  # weight * Kp of the damping task (times q_rest - q)
    "joint_kp",  # joint task (CR's joint targets)
    "joint_kd",
    "joint_weight",
    "col_kp",  # collision task (third row; target 0 penetration)
    "col_kd",
    "col_weight",
    "drift",  # 1: subtract the drift J_dot v of the TCP tasks (the original: 0, no drift term)
)
(
    POS_KP, POS_KD, POS_WEIGHT, AXIS_KP, AXIS_KD, AXIS_WEIGHT, DAMPING_VELOCITY, DAMPING_POSTURE,
    JOINT_KP, JOINT_KD, JOINT_WEIGHT, COL_KP, COL_KD, COL_WEIGHT, DRIFT,
) = range(len(PARAM_SCALARS))  # fmt: skip
HDIAG = len(PARAM_SCALARS)  # diagonal of H (Eq. 4) plus the damping task's weight, n values


@lru_cache(maxsize=8)
def params_dtype(n: int) -> np.dtype:
    """Named fields over the packed constants of an n-joint controller (:func:`pack_params`).

    Every field is float64, so ``params.view(params_dtype(n))[0]`` names the packed vector's
    entries without a copy: the scalars of :data:`PARAM_SCALARS`, then ``hdiag`` (n,) and
    ``q_rest`` (n,), the damping task's posture [rad].
    """
    fields = [(name, _F8) for name in PARAM_SCALARS]
    return np.dtype([*fields, ("hdiag", _F8, (n,)), ("q_rest", _F8, (n,))])


def pack_params(
    pos: PD,
    dir_: PD,
    joint: PD,
    col: PD,
    damping: PD,
    drift: bool,
    hdiag: np.ndarray,
    q_rest: np.ndarray,
) -> np.ndarray:
    """The controller's gains, regularizer diagonal and rest posture, packed, shape (15 + 2n,).

    A plain float64 vector (a compiled call unboxes it faster than a record); the kernels read
    it at the offsets :data:`POS_KP` ... :data:`HDIAG`, and :func:`params_dtype` names them.
    """
    n = len(hdiag)
    params = np.zeros(HDIAG + 2 * n)
    p = params.view(params_dtype(n))[0]
    p["pos_kp"], p["pos_kd"], p["pos_weight"] = pos.kp, pos.kd, pos.weight
    p["axis_kp"], p["axis_kd"], p["axis_weight"] = dir_.kp, dir_.kd, dir_.weight
    p["damping_velocity"] = -damping.weight * damping.kd
    p["damping_posture"] = damping.weight * damping.kp
    p["joint_kp"], p["joint_kd"], p["joint_weight"] = joint.kp, joint.kd, joint.weight
    p["col_kp"], p["col_kd"], p["col_weight"] = col.kp, col.kd, col.weight
    p["drift"] = 1.0 if drift else 0.0
    p["hdiag"], p["q_rest"] = hdiag, q_rest
    return params


def targets_size(n: int) -> int:
    """Length of the packed command targets of an n-joint controller (:func:`pack_targets`)."""
    return 2 + 12 + 2 * n


def pack_targets(
    out: np.ndarray,
    ty: np.ndarray | None,
    tyd: np.ndarray | None,
    tq: np.ndarray | None,
    tqd: np.ndarray | None,
) -> None:
    """Pack a command's targets into ``out`` (:func:`targets_size`) for the compiled solve.

    Layout: ``[has_y, has_q, y* (6), y_dot* (6), q* (n), q_dot* (n)]``; an absent target is a 0
    flag (its values are then not read), an absent velocity is zero.
    """
    n = (out.shape[0] - 14) // 2
    out[:] = 0.0
    if ty is not None:
        out[0] = 1.0
        out[2:8] = ty
        if tyd is not None:
            out[8:14] = tyd
    if tq is not None:
        out[1] = 1.0
        out[14 : 14 + n] = tq
        if tqd is not None:
            out[14 + n :] = tqd


def workspace(n: int) -> np.ndarray:
    """The compiled solve's work space for n joints: A, b, x and the factor L."""
    return np.zeros((2 * n + 2, n))
