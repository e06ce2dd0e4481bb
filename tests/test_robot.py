import mujoco
import numpy as np
import pinocchio as pin
import pytest

from amex.robot import PANDA_Q0


def _random_configs(robot, seed, n=5):
    rng = np.random.default_rng(seed)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    return [rng.uniform(lo, hi) for _ in range(n)]


def test_reduced_model_has_seven_joints_and_merged_capsules(robot):
    assert robot.model.nq == robot.model.nv == 7
    assert np.allclose(robot.q0, PANDA_Q0)
    # 39 URDF shapes (cylinder + 2 end spheres per link part) become 13 capsules
    assert len(robot.capsules) == 13
    assert all(c.radius > 0 for c in robot.capsules)


def test_tcp_at_neutral_pose_points_down(robot):
    M = robot.tcp_pose(robot.q0)
    assert np.allclose(M.translation, [0.307, 0.0, 0.487], atol=1e-3)
    assert np.allclose(M.rotation[:, 2], [0, 0, -1], atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pinocchio_and_mujoco_agree(robot, seed):
    model = robot.build_mujoco(1)
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tcp")
    pdata = robot.model.createData()
    rng = np.random.default_rng(seed)
    for q in _random_configs(robot, seed):
        v = rng.normal(size=7)
        data.qpos[:] = q
        data.qvel[:] = v
        mujoco.mj_forward(model, data)
        pin.computeAllTerms(robot.model, pdata, q, v)
        pin.updateFramePlacements(robot.model, pdata)
        M_tcp = pdata.oMf[robot.tcp_frame_id]
        assert np.abs(data.site_xpos[site] - M_tcp.translation).max() < 1e-9
        assert np.abs(data.site_xmat[site].reshape(3, 3) - M_tcp.rotation).max() < 1e-9
        jacp = np.zeros((3, 7))
        jacr = np.zeros((3, 7))
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        J = pin.getFrameJacobian(robot.model, pdata, robot.tcp_frame_id, pin.LOCAL_WORLD_ALIGNED)
        assert np.abs(jacp - J[:3]).max() < 1e-9
        assert np.abs(jacr - J[3:]).max() < 1e-9
        M_mj = np.zeros((7, 7))
        mujoco.mj_fullM(model, data, M_mj)
        M_pin = np.triu(pdata.M) + np.triu(pdata.M, 1).T
        assert np.abs(M_mj - M_pin).max() < 1e-9
        assert np.abs(data.qfrc_bias - pdata.nle).max() < 1e-9


def test_arm_does_not_collide_with_itself_in_mujoco(robot):
    model = robot.build_mujoco(1)  # an obstacle (parked far away): collision detection is on
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    obstacle = model.body("obstacle_0").id
    arm = [g for g in range(model.ngeom) if model.geom_bodyid[g] != obstacle]
    for i in arm:  # MuJoCo's filter: a pair may touch iff contype/conaffinity bits meet
        for j in arm:
            assert not model.geom_contype[i] & model.geom_conaffinity[j]
    (ball,) = [g for g in range(model.ngeom) if model.geom_bodyid[g] == obstacle]
    assert all(model.geom_contype[g] & model.geom_conaffinity[ball] for g in arm)
    data = mujoco.MjData(model)
    data.qpos[:] = robot.q0
    mujoco.mj_forward(model, data)
    assert data.ncon == 0


def test_without_obstacles_mujoco_skips_collision_detection(robot):
    model = robot.build_mujoco(0)
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
