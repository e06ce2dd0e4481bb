"""Costs of many joint-space rollouts at once, compiled: the sampling MPC's inner loop (``mppi``).

A rollout is given by M control points ``c`` (M, nv) of joint acceleration; interval h holds
``u_h = sum_m B[h, m] c_m`` (B: the sampler's interpolation, (H, M)). It starts at the measured
joint state ``(q_0, v_0)`` and integrates a double integrator (exact for a held acceleration)::

    v_{h+1} = v_h + dt u_h,    q_{h+1} = q_h + dt v_h + dt^2 / 2 u_h,    h = 0 .. H - 1

and its cost is the sum of six terms at the knots ``h = 1 .. H`` (running terms weighted by dt,
so that a weight does not depend on the number of knots), each a column of :func:`rollout_costs`'s
``terms`` (:data:`TERMS`):

* ``position``: ``w_goal_pos sum_h dt |p_h - g| + w_final_pos |p_H - g|^2``, TCP to goal (the
  running term is the distance itself, not its square, so that its pull does not vanish near
  the goal, where a squared distance loses against the acceleration cost);
* ``axis``: the same with the TCP z-axis ``z_h`` and the goal axis ``a`` (``w_goal_axis``,
  ``w_final_axis``);
* ``velocity``: ``w_vel sum_h dt |v_h|^2 + w_final_vel |v_H|^2``;
* ``acceleration``: ``w_acc sum_{h<H} dt u_h^T diag(metric) u_h`` (the plan's and CR's metric);
* ``collision``: ``w_col sum_h dt sum_(capsule, sphere) max(0, 1 - d / margin)^2``, CR's proxy
  (:mod:`amex.plan.optimizer.residuals`) on the same capsule-sphere distances, for the capsules
  that move (one fixed to the base adds the same cost to every rollout: left out);
* ``limits``: ``w_lim sum_h dt sum_j`` of the squared excursions of ``q_hj`` beyond its limits
  pulled in by ``limit_margin`` and of ``|v_hj|`` beyond the joint's speed limit.

Frames come from the compiled batched kinematics (:func:`forward_frames` of
:mod:`amex.plan.kinematics_kernels`), all knots of all rollouts of a call in one batch; the
capsule-sphere distances are those of its ``capsule_sphere_distances`` (the same segment data
and formula), computed only for the pairs that a bounding sphere about the joint's origin does
not rule out (the proxy is zero beyond the margin), which spares most pairs at most knots.
:func:`rollout_costs_numpy` is the reference the compiled version is tested against. No
derivative is taken anywhere (the sampler needs none).

Over 400 lines on purpose: the rollout model and its compiled cost kernel together, because the
model lays out the kernel's packed arguments and both must change together.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from amex.plan.batch_kinematics import BatchKinematics
from amex.plan.kinematics_kernels import forward_frames
from amex.robot import RobotModel

#: The cost terms, in the order of the columns of :func:`rollout_costs`'s ``terms``.
TERMS = ("position", "axis", "velocity", "acceleration", "collision", "limits")


class RolloutWeights(NamedTuple):
    """The weights of the rollout cost (module notes); lengths in the scene's units.

    Attributes:
        goal_position: running TCP distance to the goal [1/(m s)].
        goal_axis: running TCP z-axis error [1/s].
        final_position: TCP position error at the last knot [1/m^2].
        final_axis: TCP z-axis error at the last knot [-].
        final_velocity: joint velocity at the last knot [s^2/rad^2].
        velocity: running joint velocity [s/rad^2].
        acceleration: joint acceleration in the metric diag(H) [s^3/rad^2].
        collision: the collision proxy [1/s].
        collision_margin: distance at which the collision proxy starts [m].
        limits: excursions beyond the joint position and speed limits [1/(rad^2 s)].
        limit_margin: how far inside its position limits a joint starts to pay [rad].
    """

    goal_position: float
    goal_axis: float
    final_position: float
    final_axis: float
    final_velocity: float
    velocity: float
    acceleration: float
    collision: float
    collision_margin: float
    limits: float
    limit_margin: float


class RolloutModel(NamedTuple):
    """The arm as the rollout kernel reads it (built by :func:`rollout_model`).

    Attributes:
        local: turned joint placements, shape (njoints, 4, 3) (:class:`BatchKinematics`).
        parents: parent joint of each joint, shape (njoints,).
        cap_joint: joint of each moving collision capsule (joint >= 1), shape (C,).
        cap_ends: capsule segment start and vector in its joint's turned frame, (C, 2, 3) [m].
        cap_inv_len2: 1 / segment length^2 (0 for a sphere), shape (C,) [1/m^2].
        cap_radius: capsule radii, shape (C,) [m].
        cap_reach: farthest capsule surface point from its joint's origin, shape (C,) [m].
        tcp_joint: the TCP frame's parent joint.
        tcp_point: the TCP origin in that joint's turned frame, shape (3,) [m].
        tcp_axis: the TCP z-axis in that frame, shape (3,).
        lower: joint position lower limits (-inf: none), shape (nv,) [rad].
        upper: joint position upper limits (+inf: none), shape (nv,) [rad].
        speed: joint speed limits, shape (nv,) [rad/s].
        metric: the acceleration metric diag(H), shape (nv,).
    """

    local: np.ndarray
    parents: np.ndarray
    cap_joint: np.ndarray
    cap_ends: np.ndarray
    cap_inv_len2: np.ndarray
    cap_radius: np.ndarray
    cap_reach: np.ndarray
    tcp_joint: int
    tcp_point: np.ndarray
    tcp_axis: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    speed: np.ndarray
    metric: np.ndarray


def rollout_model(robot: RobotModel, kin: BatchKinematics, metric: np.ndarray) -> RolloutModel:
    """The :class:`RolloutModel` of ``robot`` (its batched kinematics ``kin``; ``metric`` (nv,)).

    Limits that are not finite or wider than 2 pi either side (a continuous joint) count as none.
    """
    frame = robot.model.frames[robot.tcp_frame_id]
    joint = int(frame.parentJoint)
    turn = kin.turn[joint]
    lower = np.array(robot.model.lowerPositionLimit, dtype=float)
    upper = np.array(robot.model.upperPositionLimit, dtype=float)
    unlimited = ~(np.isfinite(lower) & np.isfinite(upper)) | (upper - lower > 4 * np.pi)
    lower[unlimited], upper[unlimited] = -np.inf, np.inf
    moving = kin.cap_joint >= 1
    ends = kin.cap_ends[moving]  # segment start and vector, in the joint's turned frame
    return RolloutModel(
        local=np.ascontiguousarray(kin.local),
        parents=kin.parents_array,
        cap_joint=np.ascontiguousarray(kin.cap_joint[moving], dtype=np.int64),
        cap_ends=np.ascontiguousarray(kin.cap_ends[moving]),
        cap_inv_len2=np.ascontiguousarray(kin.cap_inv_len2[moving]),
        cap_radius=np.ascontiguousarray(kin.cap_radius[moving]),
        cap_reach=np.linalg.norm(ends[:, 0], axis=1).clip(np.linalg.norm(ends.sum(1), axis=1))
        + kin.cap_radius[moving],
        tcp_joint=joint,
        tcp_point=turn.T @ frame.placement.translation,
        tcp_axis=turn.T @ frame.placement.rotation[:, 2],
        lower=lower,
        upper=upper,
        speed=np.array(robot.velocity_limit, dtype=float),
        metric=np.ascontiguousarray(metric, dtype=float),
    )


def integrate(q0: np.ndarray, v0: np.ndarray, acc: np.ndarray, dt: float) -> np.ndarray:
    """Knots ``q_1 .. q_H`` and ``v_1 .. v_H`` of held accelerations ``acc`` (..., H, nv).

    Returns:
        Array of shape (2, ..., H, nv): positions [rad], then velocities [rad/s].
    """
    v = v0 + dt * np.cumsum(acc, axis=-2)
    v_before = np.concatenate([np.broadcast_to(v0, v[..., :1, :].shape), v[..., :-1, :]], -2)
    q = q0 + np.cumsum(dt * v_before + 0.5 * dt * dt * acc, axis=-2)
    return np.stack([q, v])


class Workspace(NamedTuple):
    """Buffers of one kernel call of ``T`` knots (rollouts x intervals).

    Attributes:
        acc: held accelerations, shape (nv, T) [rad/s^2].
        q: joint angles, shape (nv, T) [rad].
        v: joint velocities, shape (nv, T) [rad/s].
        sin: sines of the joint angles, shape (nv, T).
        cos: their cosines, shape (nv, T).
        axes: joint frames, shape (njoints, 3, 3, T) (:class:`BatchPoses` layout).
        pos: joint origins, shape (njoints, 3, T) [m].
    """

    acc: np.ndarray
    q: np.ndarray
    v: np.ndarray
    sin: np.ndarray
    cos: np.ndarray
    axes: np.ndarray
    pos: np.ndarray

    @classmethod
    def empty(cls, model: RolloutModel, T: int) -> Workspace:
        """Uninitialized buffers for ``T`` knots."""
        nv, nj = len(model.metric), len(model.parents)
        acc, q, v, sin, cos = (np.empty((nv, T)) for _ in range(5))
        return cls(acc, q, v, sin, cos, np.empty((nj, 3, 3, T)), np.empty((nj, 3, T)))


class Rollouts:
    """:func:`rollout_costs` of one arm, interpolation and weights, with buffers kept.

    A sampling step calls it once per chunk of rollouts: keeping the buffers (one set per chunk
    size) spares the page faults of fresh allocations in every call.

    Args:
        model: the arm (:func:`rollout_model`).
        weights: the cost weights.
        B: interval accelerations from control points, shape (H, M).
    """

    def __init__(self, model: RolloutModel, weights: RolloutWeights, B: np.ndarray) -> None:
        self.model = model
        self.weights = weights
        self.B = np.ascontiguousarray(B, dtype=float)
        self._w = np.array(weights, dtype=float)
        self._spaces: dict[int, Workspace] = {}

    def costs(
        self,
        q0: np.ndarray,
        v0: np.ndarray,
        controls: np.ndarray,
        noise: np.ndarray,
        dt: float,
        goal_pos: np.ndarray,
        goal_axis: np.ndarray,
        centers: np.ndarray,
        radii: np.ndarray,
    ) -> np.ndarray:
        """The cost terms of each rollout, shape (S, len(TERMS)); one compiled call.

        Args:
            q0: start joint positions, shape (nv,) [rad].
            v0: start joint velocities, shape (nv,) [rad/s].
            controls: the control points all rollouts share, shape (M, nv) [rad/s^2].
            noise: each rollout's offsets to them, shape (S, M, nv) [rad/s^2].
            dt: knot interval [s].
            goal_pos: goal position, shape (3,) [m].
            goal_axis: goal TCP z-axis, shape (3,).
            centers: obstacle sphere centres, shape (k, 3) [m].
            radii: their radii, shape (k,) [m].
        """
        m = self.model
        noise = np.ascontiguousarray(noise, dtype=float)
        radii = np.ascontiguousarray(radii, dtype=float)
        knots = noise.shape[0] * self.B.shape[0]
        space = self._spaces.get(knots)
        if space is None:
            if len(self._spaces) >= 8:
                self._spaces.clear()
            space = self._spaces[knots] = Workspace.empty(m, knots)
        terms = np.empty((noise.shape[0], len(TERMS)))
        _rollout_kernel(
            m.local, m.parents, m.cap_joint, m.cap_ends, m.cap_inv_len2, m.cap_radius,
            m.cap_reach, m.tcp_joint, m.tcp_point, m.tcp_axis, m.lower, m.upper, m.speed,
            m.metric, self._w, self.B, np.ascontiguousarray(q0, dtype=float),
            np.ascontiguousarray(v0, dtype=float), np.ascontiguousarray(controls, dtype=float),
            noise, float(dt), np.ascontiguousarray(goal_pos, dtype=float),
            np.ascontiguousarray(goal_axis, dtype=float),
            np.ascontiguousarray(centers, dtype=float).reshape(-1, 3), radii, *space, terms,
        )  # fmt: skip
        return terms


def rollout_costs(
    model: RolloutModel,
    weights: RolloutWeights,
    q0: np.ndarray,
    v0: np.ndarray,
    acc: np.ndarray,
    dt: float,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
) -> np.ndarray:
    """The cost terms of rollouts of accelerations ``acc`` (S, H, nv) [rad/s^2], (S, len(TERMS)).

    :meth:`Rollouts.costs` with one control point per interval (B the identity), pure.
    """
    S, H, nv = np.shape(acc)
    rollouts = Rollouts(model, weights, np.eye(H))
    return rollouts.costs(q0, v0, np.zeros((H, nv)), acc, dt, goal_pos, goal_axis, centers, radii)


@numba.njit(cache=True)
def _rollout_kernel(
    local, parents, cap_joint, cap_ends, cap_inv_len2, cap_radius, cap_reach, tcp_joint,
    tcp_point, tcp_axis, lower, upper, speed, metric, w, B, q0, v0, controls, noise, dt,
    goal_pos, goal_axis, centers, radii, accs, qs, vs, sin, cos, axes, pos, terms,
):  # type: ignore[no-untyped-def]
    """The compiled :meth:`Rollouts.costs` (arguments unpacked, buffers given); fills ``terms``."""
    S, M, nv = noise.shape
    H = B.shape[0]
    C, k = cap_joint.shape[0], radii.shape[0]
    for s in range(S):  # integrate; knot h + 1 of rollout s is column s H + h
        for j in range(nv):
            q, v = q0[j], v0[j]
            for h in range(H):
                u = 0.0
                for m in range(M):
                    u += B[h, m] * (controls[m, j] + noise[s, m, j])
                q = q + dt * v + 0.5 * dt * dt * u
                v = v + dt * u
                col = s * H + h
                accs[j, col], qs[j, col], vs[j, col] = u, q, v
                sin[j, col], cos[j, col] = np.sin(q), np.cos(q)
    forward_frames(local, parents, sin, cos, axes, pos)
    collide = k > 0 and w[7] > 0.0
    margin, jm = w[8], w[10]
    reach2 = np.empty((C, k))  # beyond this squared centre distance a pair's proxy is zero
    for c in range(C):
        for o in range(k):
            reach2[c, o] = (cap_reach[c] + radii[o] + margin) ** 2
    for s in range(S):
        e_pos = e_axis = e_vel = e_acc = e_col = e_lim = 0.0
        for h in range(H):
            col = s * H + h
            d_pos = d_axis = 0.0
            for a in range(3):
                p, z = pos[tcp_joint, a, col], 0.0
                for b in range(3):
                    p += tcp_point[b] * axes[tcp_joint, b, a, col]
                    z += tcp_axis[b] * axes[tcp_joint, b, a, col]
                d_pos += (p - goal_pos[a]) ** 2
                d_axis += (z - goal_axis[a]) ** 2
            e_pos += w[0] * dt * np.sqrt(d_pos)
            e_axis += w[1] * dt * d_axis
            speed2 = limit = 0.0
            for j in range(nv):
                v, u, q = vs[j, col], accs[j, col], qs[j, col]
                speed2 += v * v
                e_acc += w[6] * dt * metric[j] * u * u
                over = max(q - (upper[j] - jm), (lower[j] + jm) - q, 0.0)
                fast = max(abs(v) - speed[j], 0.0)
                limit += over * over + fast * fast
            e_vel += w[5] * dt * speed2
            e_lim += w[9] * dt * limit
            if h == H - 1:
                e_pos += w[2] * d_pos
                e_axis += w[3] * d_axis
                e_vel += w[4] * speed2
            if collide:
                e_col += w[7] * dt * _proxy(
                    axes, pos, col, cap_joint, cap_ends, cap_inv_len2, cap_radius, reach2,
                    centers, radii, margin,
                )
        terms[s, 0], terms[s, 1], terms[s, 2] = e_pos, e_axis, e_vel
        terms[s, 3], terms[s, 4], terms[s, 5] = e_acc, e_col, e_lim


@numba.njit(cache=True, inline="always")
def _proxy(axes, pos, col, cap_joint, cap_ends, cap_inv_len2, cap_radius, reach2, centers, radii,
           margin):  # type: ignore[no-untyped-def]  # fmt: skip
    """``sum_(c, o) max(0, 1 - d / margin)^2`` at knot ``col``: d as capsule_sphere_distances."""
    proxy = 0.0
    for c in range(cap_joint.shape[0]):
        j = cap_joint[c]
        E = cap_ends[c]
        for o in range(radii.shape[0]):
            dx = pos[j, 0, col] - centers[o, 0]
            dy = pos[j, 1, col] - centers[o, 1]
            dz = pos[j, 2, col] - centers[o, 2]
            if dx * dx + dy * dy + dz * dz >= reach2[c, o]:
                continue
            x0, x1, x2 = axes[j, 0, 0, col], axes[j, 1, 0, col], axes[j, 2, 0, col]
            rx = E[0, 0] * x0 + E[0, 1] * x1 + E[0, 2] * x2 + dx  # segment start - centre
            sx = E[1, 0] * x0 + E[1, 1] * x1 + E[1, 2] * x2  # segment vector
            x0, x1, x2 = axes[j, 0, 1, col], axes[j, 1, 1, col], axes[j, 2, 1, col]
            ry = E[0, 0] * x0 + E[0, 1] * x1 + E[0, 2] * x2 + dy
            sy = E[1, 0] * x0 + E[1, 1] * x1 + E[1, 2] * x2
            x0, x1, x2 = axes[j, 0, 2, col], axes[j, 1, 2, col], axes[j, 2, 2, col]
            rz = E[0, 0] * x0 + E[0, 1] * x1 + E[0, 2] * x2 + dz
            sz = E[1, 0] * x0 + E[1, 1] * x1 + E[1, 2] * x2
            u = -(rx * sx + ry * sy + rz * sz) * cap_inv_len2[c]
            u = min(max(u, 0.0), 1.0)
            d2 = (rx + u * sx) ** 2 + (ry + u * sy) ** 2 + (rz + u * sz) ** 2
            depth = 1.0 - (np.sqrt(d2) - (cap_radius[c] + radii[o])) / margin
            if depth > 0.0:
                proxy += depth * depth
    return proxy


def rollout_costs_numpy(
    kin: BatchKinematics,
    model: RolloutModel,
    weights: RolloutWeights,
    q0: np.ndarray,
    v0: np.ndarray,
    acc: np.ndarray,
    dt: float,
    goal_pos: np.ndarray,
    goal_axis: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
) -> np.ndarray:
    """:func:`rollout_costs` in numpy, through :class:`BatchKinematics` (the reference)."""
    S, H, nv = acc.shape
    q, v = integrate(q0, v0, acc, dt)
    poses = kin.forward(q.reshape(-1, nv))
    j = model.tcp_joint
    p = poses.position[j] + np.einsum("b,bat->at", model.tcp_point, poses.rotation[j])
    z = np.einsum("b,bat->at", model.tcp_axis, poses.rotation[j])
    d_pos = ((p.T - goal_pos) ** 2).sum(-1).reshape(S, H)
    d_axis = ((z.T - goal_axis) ** 2).sum(-1).reshape(S, H)
    speed2 = (v**2).sum(-1)
    w, lm = weights, weights.limit_margin
    over = np.maximum(np.maximum(q - (model.upper - lm), (model.lower + lm) - q), 0.0)
    fast = np.maximum(np.abs(v) - model.speed, 0.0)
    terms = np.zeros((S, len(TERMS)))
    terms[:, 0] = w.goal_position * dt * np.sqrt(d_pos).sum(1) + w.final_position * d_pos[:, -1]
    terms[:, 1] = w.goal_axis * dt * d_axis.sum(1) + w.final_axis * d_axis[:, -1]
    terms[:, 2] = w.velocity * dt * speed2.sum(1) + w.final_velocity * speed2[:, -1]
    terms[:, 3] = w.acceleration * dt * (model.metric * acc**2).sum((1, 2))
    terms[:, 5] = w.limits * dt * (over**2 + fast**2).sum((1, 2))
    if len(radii) and w.collision > 0.0:
        dist = kin.capsule_distances_numpy(poses, centers, radii).distance  # (C, k, S H)
        depth = np.maximum(1.0 - dist[kin.cap_joint >= 1] / w.collision_margin, 0.0)
        terms[:, 4] = w.collision * dt * (depth**2).sum((0, 1)).reshape(S, H).sum(1)
    return terms
