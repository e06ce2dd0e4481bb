"""Gauss-Newton trajectory optimization in joint space with a banded normal-equation solve.

The paper plans its reference with "a trajectory optimizer that uses quadratic cost terms and a
Gauss-Newton optimizer" (Section IV) and continuous replanning (CR, Section IV-A) re-runs the same
optimizer every outer step, warm-started. DESIGN.md ("The original experiment": Reference plan, CR)
fixes the costs. The decision variables are the knots ``x = (q_1, ..., q_T)``, shape (T, 7) [rad];
``q_0`` is the measured start and ``q_-1 = q_0 - dt * v_0``. With residuals ``r(x)`` the cost is

    f(x) = w_acc  sum_{t=0}^{T-1} ||(q_{t+1} - 2 q_t + q_{t-1}) / dt^2||^2 dt
         + w_pos  ||p(q_T) - g||^2          + w_vel   ||(q_T - q_{T-1}) / dt||^2
         + w_axis ||z(q_T) - a||^2          + w_axvel ||J_z(q_T) (q_T - q_{T-1}) / dt||^2
         + w_col  sum_{t=1}^{T} sum_{capsule, obstacle} max(0, 1 - d / margin)^2  =  ||r(x)||^2,

with p, z the TCP position and z-axis. The collision residual ``1 - d / margin`` is the original
code's proxy cost (MLR ``kinematicsProxyCost``), per pair instead of summed over pairs first:
dimensionless, 0 at the margin and 1 at contact, summed over knots without a ``dt`` factor. So
with weight 1 one knot in contact costs 1, about 14x the whole reference plan's acceleration cost
(0.07), and the optimum keeps pairs at or just outside the margin.

Gauss-Newton solves ``(2 J^T J + lambda I) dx = -2 J^T r``. Knot-major ordering makes the matrix
banded: acceleration couples a joint with itself two knots away (offset 2n), the final terms
couple the last two knots (offset < 2n) and collisions add 7x7 blocks on the diagonal, so the
bandwidth is exactly ``2n = 14`` (not the ``3n - 1 = 20`` of dense blocks, which makes LAPACK's
banded Cholesky ~3x slower) and each step is one ``solveh_banded`` call, O(T n^3). The collision
term needs kinematics at every knot: it runs batched over all knots in numpy
(:class:`BatchKinematics`; the Panda is a serial chain of revolute joints and its collision
shapes are capsules, so capsule-sphere distances are analytic): ~1.5 us per knot, where a loop of
Pinocchio and coal calls costs 3 us per knot without contacts and 30-90 us with.
``tests/test_optimizer.py`` checks it against Pinocchio and coal (``amex.control.collision``).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import pinocchio as pin
from scipy.linalg import LinAlgError, solveh_banded

from amex.control.state import skew
from amex.errors import ConfigError, SolverError
from amex.robot import RobotModel

_LWA = pin.LOCAL_WORLD_ALIGNED
_INITIAL_DAMPING = 1.0  # Levenberg lambda of the first iteration (see solve_trajectory)
_GUARD = 0.25  # pairs within (1 + _GUARD) margins may add curvature (see solve_trajectory)
_AXES = {
    "JointModelRX": (1.0, 0.0, 0.0),
    "JointModelRY": (0.0, 1.0, 0.0),
    "JointModelRZ": (0.0, 0.0, 1.0),
}


@dataclass(frozen=True)
class TrajectoryCosts:
    """Weights of the cost terms (module docstring); the original's values (DESIGN.md).

    Attributes:
        acceleration: weight of sum_t ||q_ddot_t||^2 dt [s^3/rad^2 per unit cost].
        final_position: weight of the squared TCP position error at q_T [1/m^2].
        final_velocity: weight of the squared joint speed at the end [s^2/rad^2].
        final_axis: weight of the squared TCP z-axis error at q_T.
        final_axis_velocity: weight of the squared TCP z-axis rate at the end [s^2].
        collision: weight of sum over knots and pairs of max(0, 1 - d / margin)^2.
        collision_margin: distance below which the collision term acts [m].
    """

    acceleration: float = 1.0
    final_position: float = 1e4
    final_velocity: float = 1e3
    final_axis: float = 1e4
    final_axis_velocity: float = 1e3
    collision: float = 1.0
    collision_margin: float = 0.02  # [m]

    def __post_init__(self) -> None:
        for name in (
            "acceleration",
            "final_position",
            "final_velocity",
            "final_axis",
            "final_axis_velocity",
            "collision",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError.invalid(f"costs.{name}", value, "a finite weight >= 0")
        if not (math.isfinite(self.collision_margin) and self.collision_margin > 0.0):
            raise ConfigError.invalid("costs.collision_margin", self.collision_margin, "> 0 [m]")


@dataclass(frozen=True, eq=False)
class TrajectoryProblem:
    """One trajectory optimization: start state, horizon, goal, obstacles and costs.

    Arrays are copied to float arrays at construction; bad shapes, ranges or non-finite values
    raise :class:`SolverError` carrying the problem.

    Attributes:
        q_start: measured joint position at the horizon start, shape (7,) [rad].
        v_start: measured joint velocity, shape (7,) [rad/s]; defines q_-1 = q_start - dt v_start.
        steps: T, the number of free knots q_1..q_T.
        dt: knot spacing [s].
        goal_pos: TCP goal position in the world frame, shape (3,) [m].
        goal_axis: TCP goal z-axis in the world frame (unit), shape (3,).
        obstacles: sphere centres, shape (k, 3) [m]; k may be 0.
        obstacle_radii: sphere radii, shape (k,) [m].
        costs: weights of the cost terms.
    """

    q_start: np.ndarray
    v_start: np.ndarray
    steps: int
    dt: float
    goal_pos: np.ndarray
    goal_axis: np.ndarray
    obstacles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    obstacle_radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    costs: TrajectoryCosts = field(default_factory=TrajectoryCosts)

    def __post_init__(self) -> None:
        names = ("q_start", "v_start", "goal_pos", "goal_axis", "obstacles", "obstacle_radii")
        for name in names:
            object.__setattr__(self, name, np.array(getattr(self, name), dtype=float))
        if self.obstacles.size == 0:
            object.__setattr__(self, "obstacles", np.zeros((0, 3)))
        n, k = max(self.q_start.size, 1), self.obstacle_radii.size
        shapes = ((n,), (n,), (3,), (3,), (k, 3), (k,))
        for name, shape in zip(names, shapes, strict=True):
            value = getattr(self, name)
            if value.shape != shape:
                raise SolverError(f"trajectory problem: {name} has shape {value.shape}", self)
            if not np.all(np.isfinite(value)):
                raise SolverError(f"trajectory problem: non-finite {name}={value}", self)
        if int(self.steps) != self.steps or self.steps < 1:
            raise SolverError(f"trajectory problem: steps={self.steps}; valid: integer >= 1", self)
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise SolverError(f"trajectory problem: dt={self.dt}; valid: > 0 [s]", self)


class TrajectorySolution(NamedTuple):
    """Result of :func:`solve_trajectory`.

    Attributes:
        q: knots including the start as row 0, shape (T + 1, 7) [rad].
        cost: f at ``q``.
        iterations: iterations used (one banded solve and one cost evaluation each, whether the
            step was taken or not).
        converged: whether the step or the relative cost decrease fell below the tolerance.
    """

    q: np.ndarray
    cost: float
    iterations: int
    converged: bool


class NormalEquations(NamedTuple):
    """Gauss-Newton model of f at x, ``f(x + dx) ~ f + gradient . dx + dx^T hessian dx / 2``.

    Attributes:
        hessian: ``2 J^T J`` in LAPACK lower band storage (``solveh_banded(..., lower=True)``),
            ``hessian[i - j, j] = H[i, j]`` for ``0 <= i - j <= 2n``, shape (2n + 1, nT).
        gradient: ``2 J^T r``, shape (nT,) for knots q_1..q_T stacked knot-major.
        cost: f(x).
    """

    hessian: np.ndarray
    gradient: np.ndarray
    cost: float


class BatchPoses(NamedTuple):
    """Joint frames of one configuration per knot, in the world frame.

    Coordinates come first and knots last (long contiguous rows for numpy). Each joint frame is
    turned about its origin so that its rotation axis is its z-axis (no turn for the Panda's
    RZ joints, whose frames are Pinocchio's ``oMi``).

    Attributes:
        rotation: joint frame orientations by columns, ``rotation[j, b, :, t] = R_j[:, b]`` at
            knot t, shape (njoints, 3, 3, T); j = 0 is the universe.
        position: joint origins, shape (njoints, 3, T) [m].
        axis: joint rotation axes ``R_j[:, 2]``, shape (njoints, 3, T).
    """

    rotation: np.ndarray
    position: np.ndarray
    axis: np.ndarray


class CapsuleDistances(NamedTuple):
    """Signed distances between every arm capsule and every obstacle sphere at every knot.

    Attributes:
        distance: signed surface distance, shape (C, k, T) [m] (negative when penetrating).
        offset: closest point on the capsule's axis segment minus the obstacle centre, shape
            (C, k, 3, T) [m]. Its direction is the unit normal n from obstacle to arm; the
            witness point on the arm's surface is ``centre + offset - radius * n``.
    """

    distance: np.ndarray
    offset: np.ndarray


class BatchKinematics:
    """Forward kinematics and capsule-sphere distances of a revolute serial arm, batched over knots.

    Args:
        robot: the arm; every joint must be a 1-DoF revolute joint with ``idx_v == joint - 1``.

    Raises:
        ConfigError: for other joint types.
    """

    def __init__(self, robot: RobotModel) -> None:
        model = robot.model
        self.njoints = int(model.njoints)
        self.parents = [int(p) for p in model.parents]
        turn = [np.eye(3)]  # per joint: rotation taking the frame's z-axis to the joint axis
        self.local = np.zeros((self.njoints, 4, 3))  # rows: (turned) A^T, then b^T
        support = np.zeros((self.njoints, model.nv), dtype=bool)
        for j in range(1, self.njoints):
            joint = model.joints[j]
            name = joint.shortname()
            if name in _AXES:
                axis = np.array(_AXES[name])
            elif name == "JointModelRevoluteUnaligned":
                axis = np.array(joint.axis, dtype=float)
            else:
                raise ConfigError.invalid("joint type", name, [*_AXES, "RevoluteUnaligned"])
            if joint.idx_v != j - 1 or joint.nv != 1:
                raise ConfigError.invalid("joint index", joint.idx_v, f"{j - 1} (serial chain)")
            turn.append(pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), axis).matrix())
            M, parent_turn = model.jointPlacements[j], turn[self.parents[j]]
            self.local[j, :3] = (parent_turn.T @ M.rotation @ turn[j]).T
            self.local[j, 3] = parent_turn.T @ M.translation
            support[j] = support[self.parents[j]]
            support[j, j - 1] = True
        caps = robot.capsules
        self.cap_joint = np.array([c.joint_id for c in caps], dtype=int)
        self.cap_radius = np.array([c.radius for c in caps])
        self.cap_support = support[self.cap_joint]  # (C, nv)
        # Per joint: its capsules and their segment start and start-to-end vector (turned frame).
        self.cap_groups = []
        for j in sorted(set(self.cap_joint.tolist())):
            idx = np.flatnonzero(self.cap_joint == j)
            ends = []
            for c in idx:
                M, h = caps[c].placement, caps[c].half_length
                ends.append(turn[j].T @ M.act(np.array([0.0, 0.0, -h])))
                ends.append(turn[j].T @ (2.0 * h * M.rotation[:, 2]))
            self.cap_groups.append((j, idx, np.array(ends)))  # (2 C_j, 3)
        self.cap_inv_len2 = np.array(
            [1.0 / (4 * c.half_length**2) if c.half_length > 0 else 0.0 for c in caps]
        )

    def forward(self, q: np.ndarray) -> BatchPoses:
        """Joint frames at each row of ``q``, shape (T, nv) [rad].

        Per joint: ``R_j = R_parent A_j Rz(q_j)`` and ``p_j = p_parent + R_parent b_j`` with the
        (turned) joint placement ``(A_j, b_j)``, evaluated for all knots at once.
        """
        T = q.shape[0]
        axes = np.empty((self.njoints, 3, 3, T))  # axes[j, b] = column b of R_j
        pos = np.empty((self.njoints, 3, T))
        axes[0] = np.eye(3)[:, :, None]
        pos[0] = 0.0
        sin, cos = np.sin(q.T), np.cos(q.T)
        for j in range(1, self.njoints):
            p = self.parents[j]
            B = (self.local[j] @ axes[p].reshape(3, 3 * T)).reshape(4, 3, T)
            R = axes[j]
            np.multiply(B[0], cos[j - 1], out=R[0])
            R[0] += B[1] * sin[j - 1]
            np.multiply(B[1], cos[j - 1], out=R[1])
            R[1] -= B[0] * sin[j - 1]
            R[2] = B[2]
            np.add(pos[p], B[3], out=pos[j])
        return BatchPoses(axes, pos, axes[:, 2])

    def capsule_distances(
        self, poses: BatchPoses, centers: np.ndarray, radii: np.ndarray
    ) -> CapsuleDistances:
        """Distances of every capsule to every sphere (``centers`` (k, 3) [m], ``radii`` (k,))."""
        T, C, k = poses.position.shape[2], len(self.cap_joint), len(radii)
        start, seg = np.empty((C, 3, T)), np.empty((C, 3, T))  # capsule axis segments, world
        for j, idx, ends in self.cap_groups:
            world = (ends @ poses.rotation[j].reshape(3, 3 * T)).reshape(-1, 3, T)
            start[idx] = world[0::2] + poses.position[j]
            seg[idx] = world[1::2]
        distance, offset = np.empty((C, k, T)), np.empty((C, k, 3, T))
        for o in range(k):
            to_start = start - centers[o][:, None]
            u = np.einsum("cat,cat->ct", to_start, seg)
            u *= -self.cap_inv_len2[:, None]
            np.clip(u, 0.0, 1.0, out=u)  # closest point: start + u seg
            off = offset[:, o]
            np.multiply(u[:, None], seg, out=off)
            off += to_start
            norm = np.sqrt(np.einsum("cat,cat->ct", off, off))
            np.subtract(norm, self.cap_radius[:, None] + radii[o], out=distance[:, o])
        return CapsuleDistances(distance, offset)

    def distance_gradients(
        self,
        poses: BatchPoses,
        dist: CapsuleDistances,
        centers: np.ndarray,
        index: tuple[np.ndarray, ...],
    ) -> np.ndarray:
        """Gradients dd/dq of the pairs ``index = (capsule, obstacle, knot)``, shape (P, nv).

        ``dd/dq_i = n . (z_i x (x - p_i)) = z_i . (x x n) + n . (p_i x z_i)`` for the joints i
        supporting the capsule, with n the unit normal, x the closest axis point and z_i, p_i
        joint i's world axis and origin: ``n^T J_point`` with Pinocchio's LOCAL_WORLD_ALIGNED
        joint Jacobian, written with the axis lines' Plucker coordinates (z_i, p_i x z_i).
        """
        c, o, t = index
        used = np.zeros(poses.axis.shape[2], dtype=bool)
        used[t] = True
        knots, which = np.flatnonzero(used), np.cumsum(used)[t] - 1  # knots[which] == t
        z, p = poses.axis[1:, :, knots], poses.position[1:, :, knots]  # (nv, 3, U)
        lines = np.empty((len(knots), 6, z.shape[0]))  # per knot: rows z, p x z; column = joint
        lines[:, :3] = z.transpose(2, 1, 0)
        for a, (b, d) in enumerate(((1, 2), (2, 0), (0, 1))):
            lines[:, 3 + a] = (p[:, b] * z[:, d] - p[:, d] * z[:, b]).T
        offset = dist.offset[c, o, :, t]  # (P, 3)
        n = offset / np.maximum(np.sqrt(np.einsum("pa,pa->p", offset, offset)), 1e-12)[:, None]
        x = centers[o] + offset
        wn = np.empty((len(c), 6))  # rows (x x n, n)
        wn[:, 0] = x[:, 1] * n[:, 2] - x[:, 2] * n[:, 1]
        wn[:, 1] = x[:, 2] * n[:, 0] - x[:, 0] * n[:, 2]
        wn[:, 2] = x[:, 0] * n[:, 1] - x[:, 1] * n[:, 0]
        wn[:, 3:] = n
        return np.einsum("pa,pai->pi", wn, lines[which]) * self.cap_support[c]


_KINEMATICS: dict[int, tuple[weakref.ref, BatchKinematics]] = {}


def batch_kinematics(robot: RobotModel) -> BatchKinematics:
    """The :class:`BatchKinematics` of ``robot``, built once per robot object and reused."""
    entry = _KINEMATICS.get(id(robot))
    if entry is not None and entry[0]() is robot:
        return entry[1]
    kin = BatchKinematics(robot)
    if len(_KINEMATICS) >= 8:
        _KINEMATICS.clear()
    _KINEMATICS[id(robot)] = (weakref.ref(robot), kin)
    return kin


@lru_cache(maxsize=8)
def _acceleration_band(n: int, T: int, dt: float, weight: float) -> np.ndarray:
    """``2 J_acc^T J_acc`` in lower band storage (2n subdiagonals), shape (2n + 1, nT); read-only.

    J_acc is ``sqrt(weight dt) / dt^2`` times the second-difference operator D on the free knots,
    so the matrix is ``kron(D^T D, I_n)`` scaled; D^T D is pentadiagonal with the entries below.
    """
    k = np.arange(T)
    inside1, inside2 = (k + 1 <= T - 1).astype(float), (k + 2 <= T - 1).astype(float)
    scale = 2.0 * weight / dt**3
    band = np.zeros((2 * n + 1, n * T))
    band[0] = scale * np.repeat(1.0 + 4.0 * inside1 + inside2, n)
    band[n, : n * max(T - 1, 0)] = scale * np.repeat(-2.0 * inside1[:-1] - 2.0 * inside2[:-1], n)
    band[2 * n, : n * max(T - 2, 0)] = scale * np.repeat(inside2[:-2], n)
    band.flags.writeable = False
    return band


@lru_cache(maxsize=4)
def _lower_triangle(m: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the lower triangle of an (m, m) matrix, ``i >= j``."""
    i, j = np.tril_indices(m)
    return i, j


def _add_block(band: np.ndarray, block: np.ndarray, first: int) -> None:
    """Add a symmetric ``block`` starting at row/column ``first`` to a lower band matrix."""
    i, j = _lower_triangle(block.shape[0])
    band.ravel()[(i - j) * band.shape[1] + first + j] += block[i, j]


def _final_terms(
    model: pin.Model,
    data: pin.Data,
    fid: int,
    problem: TrajectoryProblem,
    q_prev: np.ndarray,
    q_last: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of the four final terms, shape (m,), and their Jacobian, shape (m, 2n).

    The Jacobian columns are (q_{T-1}, q_T). Rows: position, joint velocity, axis, axis rate.
    The axis-rate derivative uses ``d omega / d q_i = z_i x sum_{k>i} z_k v_k`` (serial chain).
    """
    c, dt, n = problem.costs, problem.dt, len(q_last)
    pin.computeJointJacobians(model, data, q_last)
    oMf = pin.updateFramePlacement(model, data, fid)
    J = pin.getFrameJacobian(model, data, fid, _LWA)
    z = oMf.rotation[:, 2]
    Jw = J[3:]
    Jz = -skew(z) @ Jw
    v = (q_last - q_prev) / dt
    omega_after = np.cumsum((Jw * v)[:, ::-1], axis=1)[:, ::-1] - Jw * v  # sum_{k>i} z_k v_k
    domega = np.stack(
        [
            Jw[1] * omega_after[2] - Jw[2] * omega_after[1],
            Jw[2] * omega_after[0] - Jw[0] * omega_after[2],
            Jw[0] * omega_after[1] - Jw[1] * omega_after[0],
        ]
    )
    dzdot = -skew(z) @ domega + skew(Jw @ v) @ Jz
    w = np.sqrt([c.final_position, c.final_velocity, c.final_axis, c.final_axis_velocity])
    residual = np.concatenate(
        [
            w[0] * (oMf.translation - problem.goal_pos),
            w[1] * v,
            w[2] * (z - problem.goal_axis),
            w[3] * (Jz @ v),
        ]
    )
    jac = np.zeros((9 + n, 2 * n))
    eye = np.eye(n) / dt
    jac[0:3, n:] = w[0] * J[:3]
    jac[3 : 3 + n, :n], jac[3 : 3 + n, n:] = -w[1] * eye, w[1] * eye
    jac[3 + n : 6 + n, n:] = w[2] * Jz
    jac[6 + n :, :n], jac[6 + n :, n:] = -w[3] * Jz / dt, w[3] * (Jz / dt + dzdot)
    return residual, jac


class _Guard(NamedTuple):
    """Collision pairs within ``1 + _GUARD`` margins and their ``2 J^T J`` blocks."""

    pairs: tuple[np.ndarray, np.ndarray, np.ndarray]  # (capsule, obstacle, knot), sorted by knot
    outer: np.ndarray  # (P, n (n + 1) / 2) lower-triangle entries of each pair's 2 J^T J
    first: np.ndarray  # index of each knot's first pair
    flat: np.ndarray  # flat indices of the knots' blocks in the band

    def curvature(self, mask: np.ndarray) -> np.ndarray:
        """Summed blocks of the pairs in ``mask``, aligned with ``flat``."""
        return np.add.reduceat(self.outer * mask[:, None], self.first, axis=0).ravel()


class _Evaluation(NamedTuple):
    residuals: list[np.ndarray]  # acceleration (T, n), final (m,), collision (C, k, T)
    equations: NormalEquations
    guard: _Guard | None


def _evaluate(
    robot: RobotModel, data: pin.Data, problem: TrajectoryProblem, x: np.ndarray
) -> _Evaluation:
    """Residuals, normal equations and guard curvature at the free knots ``x`` (T, n) [rad].

    The guard holds ``2 J^T J`` of each collision pair within ``(1 + _GUARD)`` margins;
    :func:`solve_trajectory` may add those of inactive pairs to the matrix (never to the cost).
    """
    T, n = x.shape
    c, dt = problem.costs, problem.dt
    Q = np.empty((T + 2, n))
    Q[0], Q[1], Q[2:] = problem.q_start - dt * problem.v_start, problem.q_start, x
    s_acc = math.sqrt(c.acceleration * dt) / dt**2
    r_acc = s_acc * (Q[2:] - 2.0 * Q[1:-1] + Q[:-2])
    padded = np.zeros((T + 2, n))
    padded[:T] = r_acc
    grad = 2.0 * s_acc * (padded[:T] - 2.0 * padded[1 : T + 1] + padded[2:])
    hessian = np.array(_acceleration_band(n, T, float(dt), float(c.acceleration)))

    r_fin, J_fin = _final_terms(robot.model, data, robot.tcp_frame_id, problem, Q[-2], x[-1])
    if T == 1:  # q_{T-1} is the fixed start
        J_fin = J_fin[:, n:]
    m = J_fin.shape[1]
    grad.reshape(-1)[-m:] += 2.0 * (J_fin.T @ r_fin)
    _add_block(hessian, 2.0 * (J_fin.T @ J_fin), n * T - m)
    cost = float(r_acc.ravel() @ r_acc.ravel() + r_fin @ r_fin)

    r_col = np.zeros((len(robot.capsules), len(problem.obstacle_radii), T))
    guard = None
    if r_col.size and c.collision > 0.0:
        kin = batch_kinematics(robot)
        poses = kin.forward(x)
        margin = c.collision_margin
        dist = kin.capsule_distances(poses, problem.obstacles, problem.obstacle_radii)
        depth = 1.0 - dist.distance / margin
        knot, cap, obs = np.nonzero(depth.transpose(2, 0, 1) > -_GUARD)  # sorted by knot
        if knot.size:
            near = (cap, obs, knot)
            s_col = math.sqrt(c.collision)
            r_near = s_col * np.maximum(depth[near], 0.0)
            r_col[near] = r_near
            J_col = (-s_col / margin) * kin.distance_gradients(poses, dist, problem.obstacles, near)
            first = np.concatenate(([0], np.flatnonzero(knot[1:] != knot[:-1]) + 1))
            rows = knot[first]  # the knots with near pairs, each once
            grad[rows] += np.add.reduceat(2.0 * r_near[:, None] * J_col, first, axis=0)
            i, j = _lower_triangle(n)
            outer = 2.0 * J_col[:, i] * J_col[:, j]  # (P, n (n + 1) / 2)
            flat = ((i - j) * (n * T) + rows[:, None] * n + j).ravel()
            active = (r_near > 0.0)[:, None]
            hessian.ravel()[flat] += np.add.reduceat(outer * active, first, axis=0).ravel()
            guard = _Guard(near, outer, first, flat)
            cost += float(r_near @ r_near)
    return _Evaluation(
        [r_acc, r_fin, r_col], NormalEquations(hessian, grad.reshape(-1), cost), guard
    )


def _free_knots(robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    shape = (problem.steps + 1, robot.model.nq)
    if q.shape != shape:
        raise SolverError(f"trajectory of shape {q.shape}; expected {shape}", problem)
    return q[1:]


def build_normal_equations(
    robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray
) -> NormalEquations:
    """Gauss-Newton normal equations of ``problem`` at the trajectory ``q`` (pure).

    Args:
        robot: the arm.
        problem: the optimization problem.
        q: trajectory, shape (T + 1, 7) [rad]; row 0 is ignored (the start is ``problem.q_start``).

    Returns:
        The banded ``2 J^T J``, the gradient ``2 J^T r`` and the cost (module docstring).
    """
    x = _free_knots(robot, problem, q)
    return _evaluate(robot, robot.model.createData(), problem, x).equations


def trajectory_residuals(
    robot: RobotModel, problem: TrajectoryProblem, q: np.ndarray
) -> np.ndarray:
    """The stacked residual vector r with ``cost = r . r``, for inspection and tests (pure).

    Order: acceleration (T x n, knot-major), final position (3), final joint velocity (n), final
    axis (3), final axis rate (3), collision (capsules x obstacles x T, zeros when inactive).
    """
    ev = _evaluate(robot, robot.model.createData(), problem, _free_knots(robot, problem, q))
    return np.concatenate([r.ravel() for r in ev.residuals])


def _initial_guess(problem: TrajectoryProblem) -> np.ndarray:
    """All knots at the start (the first Gauss-Newton step is then a min-acceleration reach)."""
    return np.tile(problem.q_start, (problem.steps + 1, 1))


def solve_trajectory(
    robot: RobotModel,
    problem: TrajectoryProblem,
    q_init: np.ndarray | None = None,
    max_iterations: int = 20,
    tolerance: float = 1e-4,
    damping: float = 1e-3,
) -> TrajectorySolution:
    """Minimize the trajectory cost by Levenberg-damped Gauss-Newton.

    Each iteration is one banded Cholesky solve of ``(H + lambda I) dx = -g`` and one cost
    evaluation at ``x + dx``, so an iteration has a fixed price, as replanning needs. A step that
    does not increase the cost is taken and lambda shrinks 10x (down to ``damping``). A step that
    does is retried: if it brought collision pairs (within 1.25 margins, inactive at ``x``) into
    the margin, their ``2 J^T J`` is added to the matrix, the curvature Gauss-Newton cannot see
    while a pair is inactive (solutions hug the margin, so this is the usual cause); otherwise
    lambda grows 10x. lambda starts at ``max(damping, 1)``, which spares the first rejections
    when an obstacle appears on a warm start. The solve stops when an accepted step lowers the
    cost by less than ``tolerance`` relative, when a step is below ``tolerance`` [rad] in every
    joint, or after ``max_iterations`` iterations.

    Args:
        robot: the arm.
        problem: the optimization problem.
        q_init: initial trajectory, shape (T + 1, 7) [rad] (row 0 is replaced by the start), e.g.
            :func:`shift_warm_start` of the previous solution; default: all knots at the start.
        max_iterations: cap on iterations (solve + evaluation each).
        tolerance: stopping threshold on the relative cost decrease and on the step [rad].
        damping: smallest Levenberg term lambda on the Hessian diagonal (the original: 1e-3).

    Returns:
        The best trajectory found; the cost never increases from the initial guess.

    Raises:
        SolverError: if the cost is not finite or the Cholesky factorization fails.
        ConfigError: for invalid solver settings.
    """
    if not (damping > 0.0 and tolerance >= 0.0 and max_iterations >= 0):
        raise ConfigError.invalid(
            "solver settings",
            (max_iterations, tolerance, damping),
            "max_iterations >= 0, tolerance >= 0, damping > 0",
        )
    data = robot.model.createData()
    x = _free_knots(robot, problem, _initial_guess(problem) if q_init is None else q_init).copy()
    current = _evaluate(robot, data, problem, x)
    if not math.isfinite(current.equations.cost):
        raise SolverError(
            f"non-finite trajectory cost {current.equations.cost} at the initial guess", problem
        )
    lam = max(damping, _INITIAL_DAMPING)
    converged, iterations, guarded = False, 0, None
    while iterations < max_iterations and not converged:
        iterations += 1
        band = np.array(current.equations.hessian)
        if guarded is not None and current.guard is not None:
            band.ravel()[current.guard.flat] += current.guard.curvature(guarded)
        band[0] += lam
        try:
            step = solveh_banded(
                band,
                -current.equations.gradient,
                overwrite_ab=True,
                overwrite_b=True,
                lower=True,
                check_finite=False,
            )
        except (LinAlgError, ValueError) as e:
            raise SolverError(f"Gauss-Newton Cholesky failed: {e}", problem) from e
        step = step.reshape(x.shape)
        trial = _evaluate(robot, data, problem, x + step)
        cost, new_cost = current.equations.cost, trial.equations.cost
        if not math.isfinite(new_cost):
            raise SolverError(f"non-finite trajectory cost {new_cost}", problem)
        small_step = float(np.max(np.abs(step))) < tolerance
        if new_cost <= cost:
            converged = small_step or cost - new_cost <= tolerance * cost
            x += step
            current = trial
            lam = max(damping, lam / 10.0)
            guarded = None
        else:
            converged = small_step
            woken = None
            if current.guard is not None:  # pairs that the rejected step made active
                woken = trial.residuals[2][current.guard.pairs] > 0.0
                woken &= current.residuals[2][current.guard.pairs] == 0.0
                if guarded is not None:
                    woken &= ~guarded
            if woken is not None and woken.any():
                guarded = woken if guarded is None else guarded | woken
            else:
                lam *= 10.0
    cost = current.equations.cost
    return TrajectorySolution(np.vstack([problem.q_start, x]), cost, iterations, converged)


def shift_warm_start(solution_q: np.ndarray, steps_new: int) -> np.ndarray:
    """Warm start for the next replanning step (CR): drop the first knot, keep ``steps_new``.

    Args:
        solution_q: previous solution, shape (T + 1, 7) [rad].
        steps_new: the next horizon T'; rows past the old end repeat the old final knot.

    Returns:
        Initial trajectory, shape (T' + 1, 7) [rad]; row 0 (the old q_1) stands for the start.
    """
    if int(steps_new) != steps_new or steps_new < 1:
        raise ConfigError.invalid("steps_new", steps_new, "an integer >= 1")
    rest = np.asarray(solution_q, dtype=float)[1:]
    if len(rest) == 0:
        raise ConfigError.invalid("solution_q rows", 1, ">= 2")
    index = np.minimum(np.arange(steps_new + 1), len(rest) - 1)
    return rest[index]
