"""The robot layer: every configured robot's views agree, its scene is consistent, bad arms fail."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from amex.app.compose import CONF_DIR, load_config
from amex.core.errors import ConfigError
from amex.core.scaling import scale_value
from amex.robot import PANDA_Q0, RobotConfig, load_robot
from amex.robot.chain7 import chain7_urdf
from amex.robot.description import erd_robots_dir
from amex.robot.ik import reach
from amex.sim.scenario import ORIGINAL_REFERENCE_OFFSET, goal_grid, with_reference_goal

#: Every robot of conf/robot/ but the template for a user's own URDF.
CONFIGURED = sorted(p.stem for p in Path(CONF_DIR, "robot").glob("*.yaml") if p.stem != "urdf")


def _config(name: str):
    return load_config([f"robot={name}"])


def _random_configs(robot, seed, n=5):
    rng = np.random.default_rng(seed)
    lo = np.maximum(robot.model.lowerPositionLimit, -np.pi)
    hi = np.minimum(robot.model.upperPositionLimit, np.pi)
    return [rng.uniform(lo, hi) for _ in range(n)]


def test_every_robot_config_is_tested():
    assert {"panda", "chain7", "ur5"} <= set(CONFIGURED)


def test_reduced_panda_has_seven_joints_and_merged_capsules(robot):
    assert robot.model.nq == robot.model.nv == 7
    assert np.allclose(robot.q0, PANDA_Q0)
    # 39 URDF shapes (cylinder + 2 end spheres per link part) become 13 capsules
    assert len(robot.capsules) == 13
    assert all(c.radius > 0 and not c.fitted for c in robot.capsules)


def test_panda_tcp_at_neutral_pose_points_down(robot):
    M = robot.tcp_pose(robot.q0)
    assert np.allclose(M.translation, [0.307, 0.0, 0.487], atol=1e-3)
    assert np.allclose(M.rotation[:, 2], [0, 0, -1], atol=1e-9)


def test_chain7_is_the_authors_robot():
    robot = load_robot("chain7")
    assert robot.nv == 7 and np.allclose(robot.q0, 0.1)
    # robot.ors: start TCP (0.3648, -2.5475, 1.8312); 2.6 m from the shoulder when stretched
    assert np.allclose(robot.tcp_pose(robot.q0).translation, [0.3648, -2.5475, 1.8312], atol=1e-4)
    assert np.allclose(robot.tcp_pose(np.zeros(7)).translation, [0.0, -2.6, 2.0], atol=1e-12)
    links = [c for c in robot.capsules if c.half_length > 0]
    assert [(c.radius, c.half_length) for c in links] == [(0.1, 0.2)] * 6
    assert np.all(np.array(robot.model.effortLimit) > 0)


@pytest.mark.parametrize("name", CONFIGURED)
def test_pinocchio_and_mujoco_agree(name):
    robot = load_robot(_config(name).robot)
    n = robot.nv
    model = robot.build_mujoco(1)
    data = mujoco.MjData(model)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tcp")
    pdata = robot.model.createData()
    rng = np.random.default_rng(0)
    for q in [robot.q0, *_random_configs(robot, 0)]:
        v = rng.normal(size=n)
        data.qpos[:] = q
        data.qvel[:] = v
        mujoco.mj_forward(model, data)
        pin.computeAllTerms(robot.model, pdata, q, v)
        pin.updateFramePlacements(robot.model, pdata)
        M_tcp = pdata.oMf[robot.tcp_frame_id]
        assert np.abs(data.site_xpos[site] - M_tcp.translation).max() < 1e-9
        assert np.abs(data.site_xmat[site].reshape(3, 3) - M_tcp.rotation).max() < 1e-9
        jacp, jacr = np.zeros((3, n)), np.zeros((3, n))
        mujoco.mj_jacSite(model, data, jacp, jacr, site)
        J = pin.getFrameJacobian(robot.model, pdata, robot.tcp_frame_id, pin.LOCAL_WORLD_ALIGNED)
        assert np.abs(jacp - J[:3]).max() < 1e-9
        assert np.abs(jacr - J[3:]).max() < 1e-9
        M_mj = np.zeros((n, n))
        mujoco.mj_fullM(model, data, M_mj)
        M_pin = np.triu(pdata.M) + np.triu(pdata.M, 1).T
        assert np.abs(M_mj - M_pin).max() < 1e-9
        assert np.abs(data.qfrc_bias - pdata.nle).max() < 1e-9


@pytest.mark.parametrize("name", CONFIGURED)
def test_arm_touches_obstacles_but_never_itself_in_mujoco(name):
    robot = load_robot(_config(name).robot)
    model = robot.build_mujoco(1)  # an obstacle (parked far away): collision detection is on
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    obstacle = model.body("obstacle_0").id
    arm = [g for g in range(model.ngeom) if model.geom_bodyid[g] != obstacle]
    assert len(arm) >= len(robot.capsules)
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


def test_fitted_ur5_capsules_enclose_every_mesh_vertex():
    robot = load_robot("ur5")
    assert all(c.fitted for c in robot.capsules)
    geom = pin.buildGeomFromUrdfString(
        pin.buildModelFromXML(robot.description.urdf_text),
        robot.description.urdf_text,
        pin.GeometryType.COLLISION,
        package_dirs=list(robot.description.package_dirs),
    )
    from amex.robot.capsules import segment_distances, shape_vertices

    for cap, obj in zip(robot.capsules, geom.geometryObjects, strict=True):
        points = shape_vertices(obj)
        local = (points - cap.placement.translation) @ cap.placement.rotation  # capsule frame
        back = local @ cap.placement.rotation.T + cap.placement.translation
        assert np.allclose(back, points)
        assert segment_distances(cap, points).max() <= cap.radius + 1e-9, cap.name


@pytest.mark.parametrize("name", CONFIGURED)
def test_reference_goal_follows_the_original_offset_times_the_scale(name):
    config = _config(name)
    robot = load_robot(config.robot)
    start = robot.tcp_pose(robot.q0).translation
    scene = with_reference_goal(config.scene(), start)
    s = config.scenario.scale
    expected = start + np.array([scale_value(x, s, 1) for x in ORIGINAL_REFERENCE_OFFSET])
    assert np.abs(np.array(scene.reference_goal) - expected).max() < 1e-3  # stated: to the mm


def test_an_unknown_robot_lists_the_catalogue():
    with pytest.raises(ConfigError, match=r"invalid robot='kuka'; valid: chain7, panda, ur10"):
        load_robot("kuka")


def _ur5_copy(tmp_path: Path) -> Path:
    """The UR5 as a user's own arm: its URDF and meshes copied out of example-robot-data."""
    src = Path(erd_robots_dir()) / "ur_description"
    shutil.copytree(src / "meshes" / "ur5", tmp_path / "meshes" / "ur5")
    text = (src / "urdf" / "ur5_robot.urdf").read_text()
    text = text.replace("package://example-robot-data/robots/ur_description/meshes", "../meshes")
    (tmp_path / "urdf").mkdir()
    path = tmp_path / "urdf" / "arm.urdf"
    path.write_text(text)
    return path


def _user(path: Path, **changes) -> RobotConfig:
    config = RobotConfig(
        name="urdf",
        urdf=str(path),
        joints=["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint"]
        + ["wrist_2_joint", "wrist_3_joint"],
        tcp_frame="tool0",
        q0=[0.0, -1.73, 2.06, -1.9, -1.57, 0.0],
    )
    for key, value in changes.items():
        setattr(config, key, value)
    return config


def test_a_users_urdf_gives_the_catalogue_robot_it_copies(tmp_path):
    own = load_robot(_user(_ur5_copy(tmp_path)))
    ur5 = load_robot("ur5")
    q = np.array([0.3, -1.2, 1.5, -0.7, 0.4, 0.2])
    assert np.allclose(own.tcp_pose(q).homogeneous, ur5.tcp_pose(q).homogeneous, atol=1e-12)
    assert [(c.radius, c.half_length) for c in own.capsules] == [
        (c.radius, c.half_length) for c in ur5.capsules
    ]


def test_bad_descriptions_are_one_line_errors(tmp_path):
    path = _ur5_copy(tmp_path)
    cases = {
        "cannot read": _user(tmp_path / "missing.urdf"),
        "invalid robot.tcp_frame='flange'": _user(path, tcp_frame="flange"),
        "invalid robot.q0=.*6 finite joint angles": _user(path, q0=[0.0] * 5),
        "invalid robot.q0=.*within the joint limits; elbow_joint": _user(
            path, q0=[0.0, 0.0, 4.0, 0.0, 0.0, 0.0]
        ),
        "invalid robot.joints='gripper'": _user(path, joints=["gripper"]),
        "base to tip": _user(path, joints=list(reversed(_user(path).joints))),
    }
    for pattern, config in cases.items():
        with pytest.raises(ConfigError, match=pattern) as info:
            load_robot(config)
        assert "\n" not in str(info.value)
    broken = path.read_text().replace("../meshes/ur5/collision/forearm.stl", "../meshes/gone.stl")
    path.write_text(broken)
    with pytest.raises(ConfigError, match=r"gone\.stl"):
        load_robot(_user(path))


def test_a_joint_the_loop_cannot_drive_is_refused(tmp_path):
    text = chain7_urdf().replace('name="joint3" type="revolute"', 'name="joint3" type="prismatic"')
    path = tmp_path / "slider.urdf"
    path.write_text(text)
    config = RobotConfig(
        name="slider", urdf=str(path), joints=[f"joint{i}" for i in range(1, 8)],
        tcp_frame="tcp", q0=[0.1] * 7,
    )  # fmt: skip
    with pytest.raises(ConfigError, match="joint3 is a JointModelP.*cannot drive"):
        load_robot(config)


def test_a_users_urdf_runs_from_the_command_line(tmp_path):
    path = _ur5_copy(tmp_path)
    joints = "[shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint]"  # noqa: E501
    base = [str(Path(sys.executable).parent / "amex-run"), "robot=urdf", f"robot.urdf={path}"]
    q0 = "robot.q0=[0,-1.73,2.06,-1.9,-1.57,0]"
    args = [f"robot.joints={joints}", "robot.tcp_frame=tool0", q0]
    run = tmp_path / "run"
    ok = subprocess.run(
        [*base, *args, "task=1", "episodes=1", f"hydra.run.dir={run}"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert ok.returncode == 0, ok.stderr
    assert (run / "episodes.csv").read_text().count("\n") == 2
    bad = subprocess.run(
        [*base, *args[:-1], "robot.q0=[0,0,9,0,0,0]", "task=1", f"hydra.run.dir={tmp_path / 'x'}"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "robot.q0" in bad.stderr, bad.stderr
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
@pytest.mark.parametrize("name", CONFIGURED)
def test_every_grid_goal_is_reachable_from_q0(name):
    """Positions: all 150 + 150 goals. With the goal axis as well: all on the top-down robots; the
    original chain's axis (1, 0, 0) cannot be held at a few goals, as in the original."""
    config = _config(name)
    robot = load_robot(config.robot)
    scene = with_reference_goal(config.scene(), robot.tcp_pose(robot.q0).translation)
    axis = np.asarray(scene.goal_axis)
    for task in (1, 3):
        results = [reach(robot, goal, axis) for goal in goal_grid(scene, task)]
        assert max(r.position_error for r in results) < 1e-4, (name, task)
        with_axis = sum(r.axis_error < 1e-4 for r in results)
        assert with_axis >= (145 if name == "chain7" else 150), (name, task, with_axis)


@pytest.mark.parametrize("kind", ["device", "fifo"])
def test_a_collision_mesh_that_is_no_regular_file_is_refused_not_read(tmp_path, kind):
    """/dev/zero or a FIFO as a collision mesh would hang the mesh loader: one line instead."""
    import os

    from amex.core.errors import ConfigError
    from amex.robot.description import RobotConfig

    mesh = Path("/dev/zero") if kind == "device" else tmp_path / "link.stl"
    if kind == "fifo":
        os.mkfifo(mesh)
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(
        '<?xml version="1.0"?><robot name="arm"><link name="base"/>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
        '<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>'
        '<link name="l1"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" '
        'iyy="0.01" iyz="0" izz="0.01"/></inertial>'
        f'<collision><geometry><mesh filename="{mesh}"/></geometry></collision></link></robot>'
    )
    config = RobotConfig(name="arm", urdf=str(urdf), joints=["j1"], tcp_frame="l1", q0=[0.0])
    with pytest.raises(ConfigError, match=r"mesh='.*': a (device|FIFO); valid: a regular file"):
        load_robot(config)
