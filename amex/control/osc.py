"""Operational-space control: the paper's Eq. 4-6 as a weighted least-squares problem in q_ddot.

Each active task map i contributes ``c_i || J_i q_ddot + J_dot_i v - y_ddot*_i ||^2`` with the PD
target of Eq. 6, ``y_ddot* = Kp (y* - phi(q)) + Kd (y_dot* - phi_dot(q))``; the regularizer
``||q_ddot||_H^2`` of Eq. 4 uses ``H = reg * I`` (or ``reg * diag(metric)``, the authors' joint
metric). The minimizer solves the n x n normal equations

    (H + sum_i c_i J_i^T J_i) q_ddot = sum_i c_i J_i^T (y_ddot*_i - J_dot_i v),

and the torque is ``tau = M q_ddot + h`` (inverse dynamics with Pinocchio's model), clipped to the
joint torque limits. Unlike the original code, the drift ``J_dot v`` is included (``drift=False``
leaves it out, as the original). With ``joint_only`` a joint-target command (CR) is tracked by
the joint task alone, without the damping and collision tasks, as the authors' CR controller.

At 1 kHz the system is assembled and solved by one compiled call (:mod:`amex.control.kernels`,
Numba): :meth:`OperationalSpaceController.build_objective` returns it (pure; no solve),
:meth:`~OperationalSpaceController.build_objective_reference` assembles the same system task map by
task map in numpy (the test oracle), and :func:`solve_objective` solves a given system by LAPACK.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from scipy.linalg.lapack import dposv

from amex.control import packing
from amex.control.collision import CollisionModel
from amex.control.state import RobotState
from amex.control.tasks import AxisMap, CollisionMap, JointMap, PositionMap, ProxyMap, TaskTerms
from amex.core.compiled import kernel
from amex.core.errors import ConfigError, SolverError
from amex.core.types import PD, Command
from amex.robot import RobotModel
from amex.robot.geometry import joint_metric

#: Values of the collision task (``controller.collision_cost``): ours, the authors'.
COLLISION_COSTS = ("hinge", "proxy")


@dataclass
class ControllerGains:
    """The inner controller's terms that every method shares (Eq. 4-6); the original's values.

    Declared once: :class:`OSCGains` adds the method's task gains, and the run's
    ``controller.*`` configuration (:class:`~amex.experiment.config.ControllerConfig`) extends it.

    Attributes:
        col: collision task gains (original: Kp 2500, Kd 100).
        joint: joint-target task gains, used by CR's joint commands (original: 100, 100).
        damping: joint damping task pulling towards ``q0`` with ``kp`` (original: Kd 10 at
            precision 0.1, no stiffness; we weight it 0.01).
        margin: collision margin [m].
        reg: regularizer H = reg * I of Eq. 4 [-] (original 1e-3 with the metric below).
        metric: ``identity`` or ``original``: H = reg * diag(sqrt(n), ..., 1), the authors'
            (:func:`~amex.robot.geometry.joint_metric`).
        drift: subtract the TCP tasks' drift J_dot v (the original did not).
        joint_only: joint-target commands (CR) are tracked by the joint task alone, without the
            damping and collision tasks (the authors' CR controller).
        collision_cost: the collision task's value: ``hinge``, the penetration of the margin
            [m] (ours, :class:`~amex.control.tasks.CollisionMap`), or ``proxy``, the authors'
            dimensionless proxy cost (:class:`~amex.control.tasks.ProxyMap`).
        proxy_arm_radii: the proxy's radius of each arm capsule [m]; empty: their bounding radii.
        proxy_obstacle_radius: the proxy's radius of the obstacles [m].
    """

    col: PD = field(default_factory=lambda: PD(2500.0, 100.0, 10.0))
    joint: PD = field(default_factory=lambda: PD(100.0, 100.0, 1.0))
    damping: PD = field(default_factory=lambda: PD(0.0, 10.0, 0.01))
    margin: float = 0.02  # [m]
    reg: float = 1e-6
    metric: str = "identity"
    drift: bool = True
    joint_only: bool = False
    collision_cost: str = "hinge"
    proxy_arm_radii: list[float] = field(default_factory=list)  # [m]
    proxy_obstacle_radius: float = 0.02  # [m] the original's 0.1 m at scale 0.2

    def validate(self) -> None:
        """Raise :class:`ConfigError` for an unknown ``collision_cost``."""
        if self.collision_cost not in COLLISION_COSTS:
            raise ConfigError.invalid(
                "controller.collision_cost", self.collision_cost, COLLISION_COSTS
            )


@dataclass
class OSCGains(ControllerGains):
    """All gains of the inner controller: the shared terms plus the method's task gains.

    Attributes:
        pos: TCP position task (the method's).
        dir: TCP z-axis task (the method's).
    """

    pos: PD = field(default_factory=lambda: PD(1.0, 100.0, 1.0))
    dir: PD = field(default_factory=lambda: PD(1.0, 100.0, 0.5))

    @classmethod
    def of(cls, shared: ControllerGains, pos: PD, dir: PD) -> OSCGains:
        """The gains of a method with task gains ``pos``, ``dir`` under the ``shared`` terms."""
        terms = {f.name: getattr(shared, f.name) for f in fields(ControllerGains)}
        return cls(pos=pos, dir=dir, **terms)


class Objective(NamedTuple):
    """The normal equations ``A q_ddot = b`` of the OSC problem (A: (n, n) SPD, b: (n,))."""

    A: np.ndarray
    b: np.ndarray


class KernelMemory(NamedTuple):
    """The controller's arrays that compiled steps read and write in place (fixed for its life).

    Attributes:
        ws: the work space of :func:`~amex.control.kernels.osc_accelerations`: A, b, the
            solution x = q_ddot* (row n + 1), the Cholesky factor, shape (2n + 2, n).
        targets: the held command, packed (:func:`~amex.control.packing.pack_targets`).
        col: the collision task's ``(phi, J)``, shape (1 + n,).
        params: the constants with the damping task (:func:`~amex.control.packing.pack_params`).
        params_alone: the constants of a joint command tracked alone (``joint_only``).
        torque_low: lower torque limits, shape (n,) [N m].
        torque_high: upper torque limits, shape (n,) [N m].
    """

    ws: np.ndarray
    targets: np.ndarray
    col: np.ndarray
    params: np.ndarray
    params_alone: np.ndarray
    torque_low: np.ndarray
    torque_high: np.ndarray


def _accumulate(
    A: np.ndarray, b: np.ndarray, terms: TaskTerms, gains: PD, target: np.ndarray, target_vel
) -> None:
    """Add ``c ||J q_ddot + drift - y_ddot*||^2`` to the normal equations, in place."""
    yddot = gains.kp * (target - terms.phi) + gains.kd * (target_vel - terms.phid) - terms.drift
    cJt = gains.weight * terms.J.T
    A += cJt @ terms.J
    b += cJt @ yddot


class OperationalSpaceController:
    """The 1 kHz inner loop's controller.

    Args:
        robot: the controlled arm (its Pinocchio model is the controller's model).
        gains: task gains and weights.
        collision: arm-obstacle distance model, or ``None`` for a scene without obstacles.
        q_rest: posture the damping task pulls towards (only if ``gains.damping.kp > 0``);
            copied, read-only.
    """

    def __init__(
        self,
        robot: RobotModel,
        gains: OSCGains,
        collision: CollisionModel | None = None,
        q_rest: np.ndarray | None = None,
    ) -> None:
        self.robot = robot
        self.gains = gains
        self.pos_map = PositionMap()
        self.dir_map = AxisMap()
        self.joint_map = JointMap(robot.nv)
        self.col_map: CollisionMap | None = None
        if collision is not None and collision.n_obstacles > 0:
            gains.validate()
            if gains.collision_cost == "proxy":
                radii = gains.proxy_arm_radii
                self.col_map = ProxyMap(collision, gains.margin, radii, gains.proxy_obstacle_radius)
            else:
                self.col_map = CollisionMap(collision, gains.margin)
        self.q_rest = robot.q0.copy() if q_rest is None else np.array(q_rest, dtype=float)
        self.q_rest.flags.writeable = False  # packed into the kernel's record below
        self._zeros = np.zeros(robot.nv)
        self._zero1 = np.zeros(1)
        self._lo = -robot.torque_limit
        self._hi = robot.torque_limit
        n = robot.nv
        self._ws = packing.workspace(n)  # A, b, x = q_ddot*, L
        self._x = self._ws[n + 1]
        self._targets = np.zeros(packing.targets_size(n))  # the held command, packed
        self._command: Command | None = None  # the command packed into _targets
        self._alone = self._col_on = False
        self._col = np.zeros(1 + n)  # the collision task's (phi, J), written per step
        self._no_col = np.zeros(1 + n)
        g, H = gains, self.regularizer()
        tasks = (g.pos, g.dir, g.joint, g.col)
        self._params = packing.pack_params(
            *tasks, g.damping, g.drift, H + g.damping.weight, self.q_rest
        )
        no_damping = PD(0.0, 0.0, 0.0)  # the joint task alone (module notes)
        self._params_alone = packing.pack_params(*tasks, no_damping, g.drift, H, self.q_rest)
        self._active = self._params  # the packed constants of the held command

    def regularizer(self) -> np.ndarray:
        """The diagonal of H in Eq. 4, shape (n,)."""
        g, n = self.gains, self.robot.nv
        metric = joint_metric(g.metric, n)
        if metric:
            return g.reg * np.asarray(metric, dtype=float)
        return np.full(n, g.reg)

    @property
    def memory(self) -> KernelMemory:
        """The arrays the compiled kernels work on (:class:`KernelMemory`)."""
        return KernelMemory(
            self._ws, self._targets, self._col, self._params, self._params_alone, self._lo, self._hi
        )

    @property
    def held_params(self) -> np.ndarray:
        """The packed constants of the held command (:attr:`KernelMemory.params` or ``_alone``)."""
        return self._active

    @property
    def collision_on(self) -> bool:
        """Whether the collision task is tracked for the held command."""
        return self._col_on

    def hold(self, command: Command) -> None:
        """Pack ``command`` for the kernels (targets, task switches), as a solve does for a new one.

        The loop holds one command for a whole outer period: its arrays must not change while it
        is held (a method answers each step with a new Command).
        """
        self._hold(command)

    def solver_error(self, info: int) -> SolverError:
        """The error of a failed solve (LAPACK ``info``), carrying the system in :attr:`memory`."""
        n = self.robot.nv
        ws = self._ws
        return SolverError(
            f"OSC normal equations not positive definite (info={info})",
            Objective(ws[:n].copy(), ws[n].copy()),
        )

    def _hold(self, command: Command) -> None:
        """Pack ``command`` for the kernels, once per new command object (:meth:`hold`)."""
        packing.pack_targets(self._targets, command.y, command.yd, command.q, command.qd)
        self._alone = alone = command.q is not None and self.gains.joint_only  # (module notes)
        self._col_on = self.col_map is not None and not alone
        self._active = self._params_alone if alone else self._params
        self._command = command

    def _collision(self, state: RobotState) -> np.ndarray:
        """The collision task's ``(phi, J)`` at ``state`` for the held command."""
        if not self._col_on:
            return self._no_col
        self.col_map.terms_into(state, self._col)  # type: ignore[union-attr]
        return self._col

    def _kernel_args(self, state: RobotState, command: Command) -> tuple:
        """The arguments of the compiled kernels after their outputs (module :mod:`.kernels`)."""
        if command is not self._command:
            self._hold(command)
        col = self._collision(state)
        s = state
        return (s.J, s.v, s.q, s.H, s.acc_drift, self._targets, col, self._active)

    def build_objective(self, state: RobotState, command: Command) -> Objective:
        """The normal equations of Eq. 4-6 for ``command`` at ``state`` (pure; no solve).

        Assembled by one compiled call (:func:`amex.control.kernels.normal_equations`, in the
        fused form of docs/controller.md); :meth:`build_objective_reference` assembles the same
        system map by map, for tests.
        """
        n = self.robot.nv
        ws = np.empty((n + 1, n))
        self._command = None  # packed afresh: the command's arrays may have changed
        assemble = kernel("amex.control.kernels", "normal_equations")
        assemble(ws, *self._kernel_args(state, command))
        return Objective(ws[:n].copy(), ws[n].copy())

    def build_objective_reference(self, state: RobotState, command: Command) -> Objective:
        """The same normal equations as :meth:`build_objective`, one task map at a time."""
        g = self.gains
        A = np.diag(self.regularizer())
        b = np.zeros(self.robot.nv)
        alone = command.q is not None and g.joint_only
        if command.y is not None:
            yd = command.yd if command.yd is not None else np.zeros(6)
            pos, axis = self.pos_map.evaluate(state), self.dir_map.evaluate(state)
            if not g.drift:
                pos = pos._replace(drift=np.zeros(3))
                axis = axis._replace(drift=np.zeros(3))
            _accumulate(A, b, pos, g.pos, command.y[:3], yd[:3])
            _accumulate(A, b, axis, g.dir, command.y[3:], yd[3:])
        if command.q is not None:
            qd = command.qd if command.qd is not None else self._zeros
            _accumulate(A, b, self.joint_map.evaluate(state), g.joint, command.q, qd)
        if self.col_map is not None and not alone:
            terms = self.col_map.evaluate(state)
            if terms.phi[0] > 0.0:
                _accumulate(A, b, terms, g.col, self._zero1, self._zero1)
        if not alone:
            joint = self.joint_map.evaluate(state)
            _accumulate(A, b, joint, g.damping, self.q_rest, self._zeros)
        return Objective(A, b)

    def accelerations(self, state: RobotState, command: Command) -> np.ndarray:
        """The minimizer q_ddot* of Eq. 4, shape (7,) [rad/s^2].

        Raises:
            SolverError: if the normal equations are not positive definite (e.g. a NaN state).
        """
        return self._solve(state, command).copy()

    def _solve(self, state: RobotState, command: Command) -> np.ndarray:
        """:meth:`accelerations` into the work space (a view, overwritten by the next call)."""
        if command is not self._command:
            self._hold(command)
        col = self._no_col
        if self._col_on:
            col = self._col
            self.col_map.terms_into(state, col)  # type: ignore[union-attr]
        ws = self._ws
        info = kernel("amex.control.kernels", "osc_accelerations")(
            ws, state.J, state.v, state.q, state.H, state.acc_drift, self._targets, col,
            self._active,
        )
        if info != 0:
            raise self.solver_error(info)
        return self._x

    def torque(self, state: RobotState, command: Command) -> np.ndarray:
        """Joint torques ``tau = M q_ddot* + h``, clipped to the limits, shape (7,) [N m].

        ``M q_ddot + h`` is evaluated by Pinocchio's RNEA in one pass (no mass matrix formed).
        """
        qdd = self._solve(state, command)
        tau = pin.rnea(self.robot.model, state.data, state.q, state.v, qdd)
        kernel("amex.control.kernels", "clip_inplace")(tau, self._lo, self._hi)
        return tau

    def torque_into(self, state: RobotState, command: Command, out: np.ndarray) -> np.ndarray:
        """:meth:`torque` written into ``out`` (e.g. the simulator's applied forces); ``out``."""
        qdd = self._solve(state, command)
        tau = pin.rnea(self.robot.model, state.data, state.q, state.v, qdd)
        kernel("amex.control.kernels", "clip_into")(out, tau, self._lo, self._hi)
        return out


def solve_objective(objective: Objective) -> np.ndarray:
    """Solve ``A x = b`` by Cholesky (LAPACK ``dposv``); :class:`SolverError` if A is not SPD."""
    _, x, info = dposv(objective.A, objective.b)
    if info != 0:
        raise SolverError(f"OSC normal equations not positive definite (info={info})", objective)
    return x
