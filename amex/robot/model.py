"""One robot description, three views: Pinocchio (control), coal capsules (distances), MuJoCo.

:func:`build_robot` reads the cleaned URDF text of a :class:`~amex.robot.description.
RobotDescription` once for all three. Pinocchio loads the whole URDF and locks every joint that is
not an arm joint (a gripper's fingers) at 0 (``buildReducedModel``), leaving the arm. The
collision capsules come from the URDF's primitives or are fitted to its meshes
(:mod:`amex.robot.capsules`). MuJoCo compiles the same text with the locked joints deleted (their
bodies welded), URDF joint damping zeroed, mesh collision shapes replaced by the fitted capsules,
arm geoms that never collide with each other (``contype=1, conaffinity=0``) and mocap obstacle
spheres (``contype=0, conaffinity=1``). Pinocchio and MuJoCo agree on the TCP pose, its Jacobian,
the mass matrix and the bias forces to machine precision (``tests/test_robot.py``, every
``conf/robot/*.yaml``).

Conventions: world frame = robot base frame, z up; Jacobians are LOCAL_WORLD_ALIGNED (expressed in
the world frame at the frame origin); MuJoCo quaternions are (w, x, y, z); units are SI.
"""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import coal
import mujoco
import numpy as np
import pinocchio as pin

from amex.core.errors import ConfigError
from amex.robot.capsules import Capsule, fit_capsules, merge_primitives
from amex.robot.description import RobotDescription, urdf_joints
from amex.robot.meshes import check_collision_meshes

#: Pinocchio joint models the loop can drive: 1-DoF revolute joints.
DRIVABLE_JOINTS = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
OBSTACLE_PARK = (0.0, 0.0, -10.0)  # where an unused obstacle body waits, far below the robot [m]


@dataclass
class RobotModel:
    """The arm as Pinocchio model, capsule collision geometry and MuJoCo model factory.

    Attributes:
        name: the robot's label (``robot.name``).
        urdf_path: the URDF file every view is built from.
        model: reduced Pinocchio model of the arm, ``nq == nv``.
        capsules: collision geometry of the arm, as capsules attached to joints.
        tcp_frame_id: Pinocchio frame id of the tool centre point.
        q0: start configuration, shape (nv,) [rad].
        torque_limit: symmetric joint torque limits, shape (nv,) [N m].
        velocity_limit: joint speed limits, shape (nv,) [rad/s].
        joint_names: the arm joints, base to tip.
        description: what the model was built from (cleaned URDF text and facts).
    """

    name: str
    urdf_path: str
    model: pin.Model
    capsules: list[Capsule]
    tcp_frame_id: int
    q0: np.ndarray
    torque_limit: np.ndarray
    velocity_limit: np.ndarray
    joint_names: list[str] = field(default_factory=list)
    description: RobotDescription | None = field(default=None, repr=False, compare=False)

    @cached_property
    def zero_velocity(self) -> np.ndarray:
        """A zero joint vector, shape (nv,) (read-only; for zero-acceleration kinematics)."""
        zero = np.zeros(self.model.nv)
        zero.flags.writeable = False
        return zero

    @property
    def nv(self) -> int:
        """Number of actuated joints."""
        return int(self.model.nv)

    @cached_property
    def fingerprint(self) -> str:
        """Hex digest of everything the robot's behaviour depends on (plan cache key)."""
        d = self.description
        text = d.urdf_text if d is not None else self.urdf_path
        spec = [text, self.joint_names, self.model.frames[self.tcp_frame_id].name]
        spec += [self.torque_limit.tolist(), self.velocity_limit.tolist()]
        return hashlib.sha256(repr(spec).encode()).hexdigest()[:20]

    def tcp_pose(self, q: np.ndarray) -> pin.SE3:
        """TCP pose in the world frame at ``q`` (allocates; not for the 1 kHz loop)."""
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q)
        return data.oMf[self.tcp_frame_id].copy()

    def task_position(self, q: np.ndarray) -> np.ndarray:
        """The 6-D task state ``y = (p_tcp, z_tcp)``: TCP position [m], z-axis; shape (6,)."""
        M = self.tcp_pose(q)
        return np.concatenate([M.translation, M.rotation[:, 2]])

    def build_mujoco(self, n_obstacles: int = 0, timestep: float = 1e-3) -> mujoco.MjModel:
        """The compiled MuJoCo model with ``n_obstacles`` mocap spheres (shared; copy to edit)."""
        key = (self.fingerprint, n_obstacles, timestep)
        cached = _MUJOCO.get(key)
        if cached is None:
            if len(_MUJOCO) >= 32:
                _MUJOCO.clear()
            cached = _MUJOCO[key] = self._compile_mujoco(n_obstacles, timestep)
        return cached

    def _tcp_in_last_link(self) -> pin.SE3:
        """The TCP frame in the frame of the last arm joint (its child link's frame)."""
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, self.q0)
        last = self.model.njoints - 1
        return data.oMi[last].actInv(data.oMf[self.tcp_frame_id])

    def _compile_mujoco(self, n_obstacles: int, timestep: float) -> mujoco.MjModel:
        """Compile MuJoCo's view (module notes)."""
        d = self.description
        if d is None:  # pragma: no cover - build_robot always sets it
            raise ConfigError(f"robot {self.name!r} has no description to compile")
        joints = urdf_joints(d.urdf_text)
        fitted = [c for c in self.capsules if c.fitted]
        spec = mujoco.MjSpec.from_string(_mujoco_text(d.urdf_text, bool(fitted)))
        for eq in list(spec.equalities):
            spec.delete(eq)
        for joint in list(spec.joints):
            if joint.name not in d.joints:
                spec.delete(joint)
        for joint in spec.joints:
            joint.damping = [0.0, 0.0, 0.0]
        for geom in spec.geoms:
            geom.contype, geom.conaffinity = 1, 0
        for cap in fitted:
            body = (
                spec.worldbody
                if cap.joint_id == 0
                else spec.body(joints[self.model.names[cap.joint_id]][2])
            )
            geom = body.add_geom()
            geom.name = cap.name
            kind = "CAPSULE" if cap.half_length > 0 else "SPHERE"
            geom.type = getattr(mujoco.mjtGeom, f"mjGEOM_{kind}")
            geom.size = [cap.radius, cap.half_length, 0.0]
            geom.pos = cap.placement.translation
            geom.quat = pin.Quaternion(cap.placement.rotation).coeffs()[[3, 0, 1, 2]]
            geom.contype, geom.conaffinity = 1, 0
        spec.option.timestep = timestep
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
        if n_obstacles == 0:  # nothing the arm can touch: skip collision detection (~2 us a step)
            spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        last_link = joints[self.joint_names[-1]][2]
        tcp = self._tcp_in_last_link()
        site = spec.body(last_link).add_site()
        site.name = "tcp"
        site.pos = tcp.translation
        site.quat = pin.Quaternion(tcp.rotation).coeffs()[[3, 0, 1, 2]]
        for k in range(n_obstacles):
            body = spec.worldbody.add_body()
            body.name = f"obstacle_{k}"
            body.mocap = True
            body.pos = OBSTACLE_PARK
            geom = body.add_geom()
            geom.name = f"obstacle_{k}"
            geom.type = mujoco.mjtGeom.mjGEOM_SPHERE
            geom.size = [0.05, 0.0, 0.0]
            geom.contype, geom.conaffinity = 0, 1
            geom.rgba = [0.1, 0.1, 0.1, 1.0]
        try:
            return spec.compile()
        except ValueError as e:
            raise ConfigError(f"MuJoCo could not compile robot {self.name!r}: {e}") from e


_MUJOCO: dict[tuple, mujoco.MjModel] = {}
_PRIMITIVES = ("sphere", "cylinder", "capsule")


def _mujoco_text(text: str, drop_shapes: bool) -> str:
    """The URDF text MuJoCo compiles: no visuals, and no collision meshes or boxes if fitted."""
    root = ET.fromstring(text)
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
        if drop_shapes:
            for collision in link.findall("collision"):
                geometry = collision.find("geometry")
                kinds = [] if geometry is None else [g.tag for g in geometry]
                if not all(kind in _PRIMITIVES for kind in kinds):
                    link.remove(collision)
    return ET.tostring(root, encoding="unicode")


def _check_joints(full: pin.Model, description: RobotDescription) -> list[int]:
    """Ids of the joints to lock; :class:`ConfigError` for arm joints the loop cannot drive."""
    d = description
    names = [full.names[j] for j in range(1, full.njoints)]
    for name in d.joints:
        if name not in names:
            raise ConfigError.invalid("robot.joints", name, f"movable joints of the URDF: {names}")
        kind = full.joints[full.getJointId(name)].shortname()
        if kind not in DRIVABLE_JOINTS:
            raise ConfigError(
                f"invalid robot.joints: {name} is a {kind}, which the loop cannot drive; "
                "valid: revolute or continuous joints"
            )
    order = [n for n in names if n in d.joints]
    if order != list(d.joints):
        raise ConfigError.invalid("robot.joints", list(d.joints), f"base to tip: {order}")
    return [full.getJointId(n) for n in names if n not in d.joints]


def _limits(values: tuple[float, ...], urdf: np.ndarray, key: str, nv: int) -> np.ndarray:
    """The override ``values`` or the URDF's limits, checked to be positive and finite."""
    limit = np.array(values if values else urdf, dtype=float)
    if limit.shape != (nv,) or not (np.isfinite(limit).all() and (limit > 0).all()):
        source = f"robot.{key}" if values else f"the URDF's {key.split('_')[0]} limits"
        raise ConfigError.invalid(
            f"robot.{key}", limit.tolist(), f"{nv} finite values > 0 (from {source})"
        )
    return limit


def build_robot(description: RobotDescription) -> RobotModel:
    """The :class:`RobotModel` of ``description`` (module notes).

    Raises:
        ConfigError: one line for anything the loop cannot use: unreadable meshes, a joint it
            cannot drive, an unknown TCP frame, a start pose of the wrong length or outside the
            joint limits, missing limits.
    """
    d = description
    try:
        full = pin.buildModelFromXML(d.urdf_text)
    except (ValueError, RuntimeError) as e:
        raise ConfigError(f"invalid robot.urdf={d.urdf_path!r}: {e}") from e
    locked = _check_joints(full, d)
    check_collision_meshes(d.urdf_text, Path(d.urdf_path), d.package_dirs)
    try:
        geom = pin.buildGeomFromUrdfString(
            full, d.urdf_text, pin.GeometryType.COLLISION, package_dirs=list(d.package_dirs)
        )
    except (ValueError, RuntimeError) as e:
        raise ConfigError(f"invalid robot.urdf={d.urdf_path!r}: {e}") from e
    if locked:
        model, geom = pin.buildReducedModel(full, geom, locked, pin.neutral(full))
    else:
        model = full
    model.damping[:] = 0.0
    if not model.existFrame(d.tcp_frame):
        links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        raise ConfigError.invalid("robot.tcp_frame", d.tcp_frame, links)
    q0 = np.array(d.q0, dtype=float)
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    if q0.shape != (model.nq,) or not np.isfinite(q0).all():
        raise ConfigError.invalid("robot.q0", list(d.q0), f"{model.nq} finite joint angles [rad]")
    outside = np.flatnonzero((q0 < lo) | (q0 > hi))
    if outside.size:
        j = int(outside[0])
        raise ConfigError.invalid(
            "robot.q0", list(d.q0), f"angles within the joint limits; {d.joints[j]}: "
            f"[{lo[j]:.4g}, {hi[j]:.4g}] rad"
        )
    capsules, rest = merge_primitives(geom)
    try:
        fitted = fit_capsules(geom, rest)
    except ValueError as e:
        raise ConfigError(f"invalid robot.urdf={d.urdf_path!r}: {e}") from e
    capsules += fitted
    return RobotModel(
        name=d.name,
        urdf_path=d.urdf_path,
        model=model,
        capsules=capsules,
        tcp_frame_id=model.getFrameId(d.tcp_frame),
        q0=q0,
        torque_limit=_limits(d.torque_limit, model.effortLimit, "torque_limit", model.nv),
        velocity_limit=_limits(d.velocity_limit, model.velocityLimit, "velocity_limit", model.nv),
        joint_names=[model.names[i] for i in range(1, model.njoints)],
        description=d,
    )


def coal_shape(capsule: Capsule) -> coal.ShapeBase:
    """The coal shape of a capsule (a sphere when its half length is 0)."""
    if capsule.half_length > 0:
        return coal.Capsule(capsule.radius, 2.0 * capsule.half_length)
    return coal.Sphere(capsule.radius)
