"""The memory of one episode's compiled step (:mod:`amex.sim.step_kernel`): arrays and addresses.

:class:`StepMemory` gathers, once per episode, the arrays :func:`~amex.sim.step_kernel.episode_step`
works on: the simulator's joint state and applied forces, the TCP placement and joint Jacobians in
the episode's Pinocchio data, coal's distance results (the views of
:class:`~amex.control.collision.CollisionModel`), the controller's work space, targets and
constants (:attr:`~amex.control.osc.OperationalSpaceController.memory`), the joint history and the
loop's own state and constants. It writes their addresses into one int64 vector and keeps every
array referenced while it lives, so that the addresses stay valid.

Where a library's memory is not where a view says it is (another Pinocchio build: the TCP
placement or the joint Jacobians copied rather than referenced), the addresses point at arrays of
our own instead, and :meth:`StepMemory.sync` copies the library's values into them at every step
(the same numbers, slower); :attr:`StepMemory.zero_copy` tells which.
"""

from __future__ import annotations

import ctypes

import numpy as np
import pinocchio as pin

from amex.control.collision import CollisionModel
from amex.control.osc import OperationalSpaceController
from amex.control.tasks import ProxyMap
from amex.core.errors import InputError
from amex.core.types import Command
from amex.robot import RobotModel
from amex.sim import step_layout as sk
from amex.sim.loop import LoopConfig
from amex.sim.scenario import Scenario


def _address(a: np.ndarray) -> int:
    return int(a.__array_interface__["data"][0])


def _tcp_view(data: pin.Data, frame_id: int) -> np.ndarray | None:
    """The 12 doubles of ``data.oMf[frame_id]`` (rotation column major, translation), or None.

    A view only where Pinocchio's accessors reference its memory and the translation follows the
    rotation (``SE3Tpl``: ``rot`` then ``trans``).
    """
    placement = data.oMf[frame_id]
    rotation, translation = placement.rotation, placement.translation
    if rotation.flags.owndata or translation.flags.owndata or not rotation.flags.f_contiguous:
        return None
    if _address(translation) != _address(rotation) + 72:
        return None
    view = np.ctypeslib.as_array((ctypes.c_double * 12).from_address(_address(rotation)))
    view.flags.writeable = False
    return view


class StepMemory:
    """The arrays and the address vector of one episode's compiled step (module notes).

    Args:
        robot: the arm.
        data: the episode's Pinocchio data (the controller's state is computed into it).
        osc: the episode's controller.
        collision: its collision model, or None.
        scenario: the episode's scenario (the goal's motion).
        loop: the loop's configuration (stop radius, lag, kinematic simulation).
        dt: the inner step [s].
        history: the joint angles of every step, shape (n_steps + 1, n), written by the step.
        qpos: the simulator's joint positions (a view of its state) [rad].
        qvel: the simulator's joint velocities [rad/s].
        qfrc: the simulator's applied joint forces, where the clipped torque goes [N m].
        in_place: read the TCP placement and joint Jacobians in Pinocchio's memory where its
            layout allows; False: always through copies (:meth:`sync`; tests).

    Attributes:
        mem: the address vector, length :data:`~amex.sim.step_layout.ADDRESSES`.
        loop_state: the loop's state (path length, distance, goal, ...), as the kernel leaves it.
        zero_copy: the TCP placement and joint Jacobians are read in place (no :meth:`sync`).
        command: the command last held (:meth:`hold`).
    """

    def __init__(
        self,
        robot: RobotModel,
        data: pin.Data,
        osc: OperationalSpaceController,
        collision: CollisionModel | None,
        scenario: Scenario,
        loop: LoopConfig,
        dt: float,
        history: np.ndarray,
        qpos: np.ndarray,
        qvel: np.ndarray,
        qfrc: np.ndarray,
        in_place: bool = True,
    ) -> None:
        n = robot.nv
        self.osc, self.data, self.frame_id = osc, data, robot.tcp_frame_id
        for name, a in (("qpos", qpos), ("qvel", qvel), ("qfrc", qfrc), ("history", history)):
            if a.dtype != np.float64 or not a.flags.c_contiguous:
                raise InputError(f"{name}: a C-contiguous float64 array is needed")
        mem = np.zeros(sk.ADDRESSES, dtype=np.int64)
        self._keep: list[np.ndarray] = []  # every array whose address is in mem

        def put(slot: int, a: np.ndarray) -> None:
            self._keep.append(a)
            mem[slot] = _address(a)

        tcp = _tcp_view(data, self.frame_id)
        joint_jacobians = data.J
        zero_copy = in_place and tcp is not None and not joint_jacobians.flags.owndata
        zero_copy = zero_copy and joint_jacobians.flags.f_contiguous
        self.zero_copy = zero_copy
        self._tcp = tcp if zero_copy and tcp is not None else np.zeros(12)
        self._joint_jacobians = joint_jacobians if zero_copy else np.zeros((n, 6)).T
        put(sk.QPOS, qpos)
        put(sk.QVEL, qvel)
        put(sk.TCP_POSE, self._tcp)
        put(sk.JOINT_JACOBIANS, self._joint_jacobians)
        put(sk.HISTORY, history)
        memory = osc.memory
        put(sk.WORKSPACE, memory.ws)
        put(sk.TARGETS, memory.targets)
        put(sk.COL, memory.col)
        put(sk.PARAMS, osc.held_params)
        self._keep += [memory.params, memory.params_alone]  # (hold switches between them)
        self._alone = memory.params_alone
        self._params_at = _address(memory.params), _address(memory.params_alone)
        put(sk.TORQUE_LOW, memory.torque_low)
        put(sk.TORQUE_HIGH, memory.torque_high)
        put(sk.TORQUE_OUT, qfrc)
        speed_limit = loop.speed_limit_factor * robot.velocity_limit
        put(sk.SPEED_LIMIT, np.ascontiguousarray(speed_limit, dtype=float))
        self.x = memory.ws[n + 1]  # q_ddot* of the last CONTROL phase (a view)

        goal = scenario.goal_at(0.0)
        moves = bool(np.any(scenario.goal_velocity))
        const = np.zeros(sk.CONSTANTS_SIZE)
        const[sk.DT], const[sk.STOP_RADIUS] = dt, loop.stop_radius
        const[sk.GOAL_START : sk.GOAL_START + 3] = scenario.goal_start
        const[sk.GOAL_VELOCITY : sk.GOAL_VELOCITY + 3] = scenario.goal_velocity
        const[sk.GOAL_STOP_TIME] = scenario.goal_stop_time
        const[sk.GOAL_MOVES_UNTIL] = scenario.goal_stop_time if moves else -1.0
        const[sk.SQUARE] = 2.0
        self.loop_state = state = np.zeros(sk.LOOP_SIZE)
        state[sk.GOAL_X : sk.GOAL_X + 3] = goal
        state[sk.DISTANCE] = np.inf
        put(sk.LOOP, state)
        put(sk.CONSTANTS, const)

        mem[sk.N_JOINTS], mem[sk.N_STEPS] = n, history.shape[0] - 1
        mem[sk.KINEMATIC], mem[sk.LAG] = int(loop.kinematic), int(loop.state_lag)
        self._kind = sk.NO_COLLISION
        col_map = osc.col_map
        if collision is not None and col_map is not None and collision.pair_arm.size:
            self._kind = sk.PROXY if isinstance(col_map, ProxyMap) else sk.HINGE
            const[sk.MARGIN] = col_map.margin
            table, placements = collision.table, collision.placements
            for name, a in (("table", table), ("placements", placements)):
                if a.strides[1] != 8 or a.strides[0] % 8:
                    raise InputError(f"collision {name}: rows of adjacent float64 are needed")
            put(sk.TABLE, table)
            put(sk.PLACEMENTS, placements)
            put(sk.SUPPORT, np.ascontiguousarray(collision.support))
            put(sk.PAIR_OBSTACLE, np.ascontiguousarray(collision.pair_obstacle, dtype=np.int64))
            put(sk.PAIR_ARM, np.ascontiguousarray(collision.pair_arm, dtype=np.int64))
            put(sk.CENTERS, collision.centers)
            reach = col_map.reach if isinstance(col_map, ProxyMap) else [0.0] * collision.n_arm
            put(sk.REACH, np.array(reach, dtype=float))
            mem[sk.N_PAIRS], mem[sk.N_OBSTACLES] = collision.pair_arm.size, collision.n_obstacles
            mem[sk.TABLE_STRIDE] = table.strides[0] // 8
            mem[sk.PLACEMENT_STRIDE] = placements.strides[0] // 8
            mem[sk.N_GEOMS], mem[sk.N_ARM] = placements.shape[0], collision.n_arm
        self.mem = mem
        self.command: Command | None = None
        self.collision_on = False

    def hold(self, command: Command) -> None:
        """Hold ``command``: the controller packs it, the step reads its constants and switches."""
        osc = self.osc
        osc.hold(command)
        self.mem[sk.PARAMS] = self._params_at[osc.held_params is self._alone]
        self.collision_on = osc.collision_on and self._kind != sk.NO_COLLISION
        self.mem[sk.COLLISION] = self._kind if self.collision_on else sk.NO_COLLISION
        self.command = command

    def sync(self) -> None:
        """Copy the TCP placement and joint Jacobians into our arrays (only without zero copy)."""
        placement = self.data.oMf[self.frame_id]
        self._tcp[:9] = placement.rotation.ravel(order="F")
        self._tcp[9:] = placement.translation
        self._joint_jacobians[:] = self.data.J

    def goal(self) -> np.ndarray:
        """The goal of the last MEASURE phase, shape (3,) [m] (a copy)."""
        return self.loop_state[sk.GOAL_X : sk.GOAL_X + 3].copy()

    @property
    def distance(self) -> float:
        """The TCP-goal distance of the last MEASURE phase (the stop rule's) [m]."""
        return float(self.loop_state[sk.DISTANCE])

    @property
    def path_length(self) -> float:
        """The TCP path's length so far [m]."""
        return float(self.loop_state[sk.PATH_LENGTH])

    @property
    def measured(self) -> bool:
        """Whether a MEASURE phase ran."""
        return bool(self.loop_state[sk.HAS_PREV])

    @property
    def axis(self) -> list[float]:
        """The TCP z-axis of the last MEASURE phase, as Python floats."""
        return self.loop_state[sk.AXIS_X : sk.AXIS_X + 3].tolist()

    @property
    def info(self) -> int:
        """The ``info`` of the last failed solve."""
        return int(self.loop_state[sk.INFO])
