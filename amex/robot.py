"""One robot description, three views: Pinocchio (control), coal (distances), MuJoCo (simulation).

The Franka Panda of ``example-robot-data`` (``panda_collision.urdf``: cylinders capped by spheres,
the paper's "convex shapes") is read once from the same file by all three. The two finger joints are
locked, leaving the 7-DoF arm. Pinocchio and MuJoCo agree on kinematics and mass matrix to machine
precision on this model (``tests/test_robot.py`` keeps that true).

Conventions: world frame = robot base frame, z up; Jacobians are LOCAL_WORLD_ALIGNED (expressed in
the world frame at the frame origin); MuJoCo quaternions are (w, x, y, z); units are SI.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import cache, cached_property

import coal
import mujoco
import numpy as np
import pinocchio as pin

from amex.errors import ConfigError

#: The Panda's neutral pose used as the start of every episode [rad].
PANDA_Q0 = (0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4)

ROBOTS = ("panda",)


@cache
def panda_urdf_path() -> str:
    """Absolute path of ``panda_collision.urdf`` in the installed example-robot-data."""
    import example_robot_data

    root = example_robot_data.getModelPath("panda_description")
    path = os.path.join(root, "panda_description", "urdf", "panda_collision.urdf")
    if not os.path.exists(path):
        raise ConfigError(f"panda_collision.urdf not found at {path}; reinstall example-robot-data")
    return path


@dataclass(frozen=True)
class Capsule:
    """A capsule (or sphere if ``half_length`` is 0) rigidly attached to a joint frame."""

    name: str
    joint_id: int  # Pinocchio joint the shape moves with
    placement: pin.SE3  # shape frame in the joint frame; the capsule axis is its z-axis
    radius: float  # [m]
    half_length: float  # [m]


def _merge_capsules(model: pin.Model, geom_model: pin.GeometryModel) -> list[Capsule]:
    """Turn the URDF's cylinder + two end-sphere triples into capsules; keep lone spheres/cylinders.

    A capsule is exactly the union of a cylinder and two spheres of the same radius at its end
    caps, so the merged shapes have the same distance field with a third of the distance queries.
    """
    objects = list(geom_model.geometryObjects)
    used: set[int] = set()
    capsules: list[Capsule] = []
    for i, obj in enumerate(objects):
        geo = obj.geometry
        if not isinstance(geo, coal.Cylinder):
            continue
        M = obj.placement
        ends = [M.act(np.array([0.0, 0.0, s * geo.halfLength])) for s in (-1.0, 1.0)]
        caps = []
        for j, other in enumerate(objects):
            if j in used or j == i or other.parentJoint != obj.parentJoint:
                continue
            if not isinstance(other.geometry, coal.Sphere):
                continue
            if abs(other.geometry.radius - geo.radius) > 1e-9:
                continue
            if any(np.linalg.norm(other.placement.translation - e) < 1e-3 for e in ends):
                caps.append(j)
        if len(caps) == 2:
            used.update(caps)
        used.add(i)
        half = geo.halfLength if len(caps) == 2 else geo.halfLength + geo.radius
        # A cylinder without caps is approximated by the enclosing capsule (conservative).
        capsules.append(Capsule(obj.name, obj.parentJoint, M, float(geo.radius), float(half)))
    for j, obj in enumerate(objects):
        if j not in used and isinstance(obj.geometry, coal.Sphere):
            capsules.append(
                Capsule(obj.name, obj.parentJoint, obj.placement, float(obj.geometry.radius), 0.0)
            )
    return capsules


@dataclass
class RobotModel:
    """The arm as Pinocchio model, capsule collision geometry and MuJoCo model factory.

    Attributes:
        name: robot name (a key of :data:`ROBOTS`).
        urdf_path: the URDF every view is built from.
        model: reduced Pinocchio model (fingers locked), ``nq == nv == 7``.
        capsules: collision geometry of the arm, as capsules attached to joints.
        tcp_frame_id: Pinocchio frame id of the tool centre point.
        q0: start configuration, shape (7,) [rad].
        torque_limit: symmetric joint torque limits, shape (7,) [N m].
        velocity_limit: joint speed limits, shape (7,) [rad/s].
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

    @cached_property
    def zero_velocity(self) -> np.ndarray:
        """A zero joint vector, shape (7,) (read-only; for zero-acceleration kinematics)."""
        zero = np.zeros(self.model.nv)
        zero.flags.writeable = False
        return zero

    @property
    def nv(self) -> int:
        """Number of actuated joints."""
        return int(self.model.nv)

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
        """Compile the MuJoCo model with ``n_obstacles`` mocap spheres (:func:`_mujoco_model`)."""
        return _mujoco_model(self.urdf_path, self._tcp_in_link7(), n_obstacles, timestep)

    def _tcp_in_link7(self) -> tuple[float, ...]:
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, self.q0)
        link7 = self.model.getJointId("panda_joint7")
        M = data.oMi[link7].actInv(data.oMf[self.tcp_frame_id])
        return tuple(M.translation) + tuple(pin.Quaternion(M.rotation).coeffs()[[3, 0, 1, 2]])


def load_robot(name: str = "panda", q0: tuple[float, ...] | None = None) -> RobotModel:
    """Build the :class:`RobotModel` for ``name`` (only ``"panda"`` so far)."""
    if name not in ROBOTS:
        raise ConfigError.invalid("robot", name, ROBOTS)
    urdf = panda_urdf_path()
    full = pin.buildModelFromUrdf(urdf)
    geom = pin.buildGeomFromUrdf(full, urdf, pin.GeometryType.COLLISION)
    locked = [full.getJointId(n) for n in ("panda_finger_joint1", "panda_finger_joint2")]
    model, geom = pin.buildReducedModel(full, geom, locked, pin.neutral(full))
    model.damping[:] = 0.0
    start = np.array(PANDA_Q0 if q0 is None else q0, dtype=float)
    if start.shape != (model.nq,):
        raise ConfigError.invalid("robot.q0", list(start), f"{model.nq} joint angles [rad]")
    return RobotModel(
        name=name,
        urdf_path=urdf,
        model=model,
        capsules=_merge_capsules(model, geom),
        tcp_frame_id=model.getFrameId("panda_hand_tcp"),
        q0=start,
        torque_limit=np.array(model.effortLimit, dtype=float),
        velocity_limit=np.array(model.velocityLimit, dtype=float),
        joint_names=[model.names[i] for i in range(1, model.njoints)],
    )


OBSTACLE_PARK = (0.0, 0.0, -10.0)  # where an unused obstacle body waits, far below the robot [m]


@cache
def _mujoco_model(
    urdf: str, tcp_site: tuple[float, ...], n_obstacles: int, timestep: float
) -> mujoco.MjModel:
    """Compile the Panda for MuJoCo, fixed as DESIGN.md records.

    The finger ``<mimic>`` equality and finger joints are removed (fingers are welded to the
    hand, as in the reduced Pinocchio model); URDF joint damping is zeroed (Pinocchio's model has
    none); arm geoms get ``contype=1, conaffinity=0`` so the arm never collides with itself;
    obstacles are mocap spheres ``obstacle_<k>`` with ``contype=0, conaffinity=1`` so they touch
    only the arm; without obstacles no pair can touch, so collision detection is switched off. The
    arm is torque controlled through ``qfrc_applied``; a ``tcp`` site marks the
    tool centre point.
    """
    spec = mujoco.MjSpec.from_file(urdf)
    for eq in list(spec.equalities):
        spec.delete(eq)
    for joint in list(spec.joints):
        if "finger" in joint.name:
            spec.delete(joint)
    for joint in spec.joints:
        joint.damping = [0.0, 0.0, 0.0]
    for geom in spec.geoms:
        geom.contype, geom.conaffinity = 1, 0
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_EULER
    if n_obstacles == 0:  # nothing the arm can touch: skip collision detection (~2 us a step)
        spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    link7 = spec.body("panda_link7")
    site = link7.add_site()
    site.name = "tcp"
    site.pos = tcp_site[:3]
    site.quat = tcp_site[3:]
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
    except ValueError as e:  # pragma: no cover - the shipped URDF compiles
        raise ConfigError(f"MuJoCo could not compile {urdf}: {e}") from e
