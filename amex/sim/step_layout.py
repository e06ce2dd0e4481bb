"""The layout of the episode step's address vector, loop state and constants.

The slots and flags :func:`amex.sim.step_kernel.episode_step` reads, apart from the compiled code
so that the Python side (:class:`amex.sim.inner_step.StepMemory`,
:func:`amex.sim.episode.run_episode`) uses them without importing Numba
(:mod:`amex.core.compiled`). The slots are documented where the kernel reads them.
"""

from __future__ import annotations

#: phases of :func:`~amex.sim.step_kernel.episode_step` (bit flags)
MEASURE, CONTROL = 1, 2
BOTH = MEASURE | CONTROL
#: what :func:`~amex.sim.step_kernel.episode_step` returns
GO_ON, STOP, SOLVER_FAILED = 0, 1, 2
#: collision task kinds (slot ``COLLISION``): off (no obstacles or not for the held command)
NO_COLLISION, HINGE, PROXY = 0, 1, 2

# slots of the address vector: the addresses of float64 arrays (int64 for the pair indices) ...
(
    QPOS, QVEL, TCP_POSE, JOINT_JACOBIANS, TABLE, PLACEMENTS, HISTORY, WORKSPACE, TARGETS, COL,
    PARAMS, TORQUE_LOW, TORQUE_HIGH, TORQUE_OUT, LOOP, CONSTANTS, SUPPORT, PAIR_OBSTACLE,
    PAIR_ARM, CENTERS, REACH, SPEED_LIMIT,
    # ... then sizes and switches
    N_JOINTS, N_PAIRS, TABLE_STRIDE, PLACEMENT_STRIDE, N_GEOMS, N_ARM, N_OBSTACLES, N_STEPS,
    KINEMATIC, LAG, COLLISION,
) = range(33)  # fmt: skip
ADDRESSES = 33

# the loop's state (slot LOOP), float64
(
    PATH_LENGTH, PREV_X, PREV_Y, PREV_Z, HAS_PREV, GOAL_X, GOAL_Y, GOAL_Z, DISTANCE, AXIS_X,
    AXIS_Y, AXIS_Z, INFO,
) = range(13)  # fmt: skip
LOOP_SIZE = 13

# the episode's constants (slot CONSTANTS), float64
(
    DT, STOP_RADIUS, GOAL_START, _GS1, _GS2, GOAL_VELOCITY, _GV1, _GV2, GOAL_STOP_TIME,
    GOAL_MOVES_UNTIL, MARGIN, SQUARE,
) = range(12)  # fmt: skip
CONSTANTS_SIZE = 12
