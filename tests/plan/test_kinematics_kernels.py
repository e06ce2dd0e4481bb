"""The compiled optimizer kernels give numpy's numbers bit for bit (sign bits included).

CR's results must not depend on which path computed them: the compiled frames, capsule
distances, final terms, near pairs and distance gradients are compared with the numpy
implementations they replaced, on random configurations of every catalogue arm, and a warm start
that reuses the last solution's frames must give the same solution as one that recomputes them.

The frames and final terms replicate the fused multiply-adds of OpenBLAS's small products, so
they are bit for bit under the kernels that fuse (Haswell, Zen, SkylakeX and later: x86-64 CPUs
with AVX2 and FMA, Intel's since 2013 and AMD's since 2017). Under an older kernel
(``OPENBLAS_CORETYPE=Prescott``, Sandybridge), which does not fuse, numpy rounds those products
differently and the two agree to ~1e-16 (:func:`same_as_numpy`); ``make test-kernels`` runs
this file under Prescott.
"""

from __future__ import annotations

import numpy as np
import pytest

from amex.plan import optimizer as opt
from amex.plan.batch_kinematics import BatchKinematics
from amex.plan.kinematics_kernels import near_pairs
from amex.plan.optimizer.final_terms import final_terms, final_terms_numpy
from amex.plan.problem import TrajectoryCosts, TrajectoryProblem
from amex.plan.weights import CollisionWeights
from amex.robot import RobotConfig, load_robot

ROBOTS = ("panda", "chain7", "ur5")


def identical(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return (
        a.shape == b.shape
        and np.array_equal(a, b, equal_nan=True)
        and np.array_equal(np.signbit(a), np.signbit(b))
    )


#: OpenBLAS cores whose small products fuse multiply-adds (what the compiled kernels replicate).
FUSING_CORES = ("Haswell", "Zen", "SkylakeX", "Cooperlake", "SapphireRapids")


def _fusing() -> bool:
    from amex.plan.cache import blas_kernel

    cores = [core.split()[0] for core in blas_kernel()["cores"]]
    return bool(cores) and all(core in FUSING_CORES for core in cores)


FUSING = _fusing()


def same_as_numpy(fast: np.ndarray, slow: np.ndarray) -> bool:
    """Bit for bit under a fusing kernel; within 1e-13 (relative, or absolute near 0) otherwise."""
    if FUSING:
        return identical(fast, slow)
    a, b = np.asarray(fast), np.asarray(slow)
    return a.shape == b.shape and np.allclose(a, b, rtol=1e-13, atol=1e-13, equal_nan=True)


@pytest.fixture(scope="module", params=ROBOTS)
def arm(request):
    robot = load_robot(RobotConfig(name=request.param))
    return robot, BatchKinematics(robot)


def _knots(robot, rng, T):
    return robot.q0 + rng.normal(scale=0.8, size=(T, robot.nv))


def _obstacles(robot, rng, k):
    reach = float(np.linalg.norm(robot.tcp_pose(robot.q0).translation))
    return rng.normal(scale=0.4 * reach, size=(k, 3)), rng.uniform(0.01, 0.1, size=k) * reach


@pytest.mark.parametrize("T", [1, 2, 3, 17, 400])
def test_compiled_frames_and_capsule_distances_equal_numpy(arm, T):
    robot, kin = arm
    rng = np.random.default_rng(T)
    for _ in range(3):
        q = _knots(robot, rng, T)
        fast, slow = kin.forward(q), kin.forward_numpy(q)
        assert same_as_numpy(fast.rotation, slow.rotation)
        assert same_as_numpy(fast.position, slow.position)
        for k in (1, 2):
            centers, radii = _obstacles(robot, rng, k)
            a = kin.capsule_distances(slow, centers, radii)
            b = kin.capsule_distances_numpy(slow, centers, radii)
            assert same_as_numpy(a.distance, b.distance) and same_as_numpy(a.offset, b.offset)


def test_compiled_distance_gradients_and_near_pairs_equal_numpy(arm):
    robot, kin = arm
    rng = np.random.default_rng(7)
    for T in (2, 40):
        poses = kin.forward(_knots(robot, rng, T))
        centers, radii = _obstacles(robot, rng, 2)
        dist = kin.capsule_distances(poses, centers, radii)
        index = tuple(np.nonzero(rng.random(dist.distance.shape) < 0.4))
        assert identical(
            kin.distance_gradients(poses, dist, centers, index),
            kin.distance_gradients_numpy(poses, dist, centers, index),
        )
        margin = float(np.median(dist.distance))
        r_col = np.zeros(dist.distance.shape)
        cap, obs, knot, r = near_pairs(dist.distance, margin, 0.25, 2.0, r_col)
        depth = 1.0 - dist.distance / margin
        expected_knot, expected_cap, expected_obs = np.nonzero(depth.transpose(2, 0, 1) > -0.25)
        assert [cap.tolist(), obs.tolist(), knot.tolist()] == [
            expected_cap.tolist(),
            expected_obs.tolist(),
            expected_knot.tolist(),
        ]
        near = (expected_cap, expected_obs, expected_knot)
        assert identical(r, 2.0 * np.maximum(depth[near], 0.0)) and identical(r_col[near], r)


def test_compiled_final_terms_equal_numpy(arm):
    robot, _ = arm
    rng = np.random.default_rng(3)
    data = robot.model.createData()
    for _ in range(50):
        problem = TrajectoryProblem(
            q_start=robot.q0,
            v_start=np.zeros(robot.nv),
            steps=2,
            dt=0.01,
            goal_pos=rng.normal(size=3),
            goal_axis=np.array([0.0, 0.0, -1.0]),
            costs=TrajectoryCosts(CollisionWeights(final_axis=float(rng.uniform(1.0, 1e4)))),
        )
        q_prev = robot.q0 + rng.normal(size=robot.nv)
        q_last = q_prev + rng.normal(scale=0.05, size=robot.nv)
        args = (robot.model, data, robot.tcp_frame_id, problem, q_prev, q_last)
        for fast, slow in zip(final_terms(*args), final_terms_numpy(*args), strict=True):
            assert same_as_numpy(fast, slow)


def test_a_warm_start_with_the_last_frames_gives_the_same_solution(robot):
    rng = np.random.default_rng(0)
    centers = np.array([[0.35, 0.12, 0.47]])
    problem = TrajectoryProblem(
        q_start=robot.q0,
        v_start=np.zeros(7),
        steps=60,
        dt=0.01,
        goal_pos=np.array([0.384, 0.229, 0.461]),
        goal_axis=np.array([0.0, 0.0, -1.0]),
        obstacles=centers,
        obstacle_radii=np.array([0.02]),
        costs=TrajectoryCosts(CollisionWeights(collision=10.0)),
    )
    first = opt.solve_trajectory(robot, problem, max_iterations=5)
    assert first.frames is not None
    shifted = np.minimum(np.arange(1, 62), 60)  # CR's shift by one knot, last repeated
    later = TrajectoryProblem(
        **{**problem.__dict__, "q_start": first.q[1] + 1e-4 * rng.normal(size=7)}
    )
    q_init = first.q[shifted]
    frames = first.frames.take(shifted[1:] - 1)
    a = opt.solve_trajectory(robot, later, q_init=q_init, init_frames=frames)
    b = opt.solve_trajectory(robot, later, q_init=q_init)
    assert identical(a.q, b.q) and a.cost == b.cost and a.iterations == b.iterations
