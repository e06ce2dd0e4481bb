"""What a robot is made of: a URDF, the arm's joints, its tool centre point, its start pose.

:class:`RobotConfig` is what a user writes (``conf/robot/*.yaml``, or ``robot=urdf`` with their
own file); the catalogue (:mod:`amex.robot.catalogue`) fills what a known robot leaves empty.
:func:`resolve` turns it into a :class:`RobotDescription`: the URDF text cleaned for the three
libraries, so that every later step reads one canonical text.

Cleaning (DESIGN.md, "Other robots"): ``<transmission>``, ``<gazebo>`` and ``<mimic>`` elements
are dropped and ``continuous`` joints become ``revolute`` with limits of +-2 pi, so that every arm
joint has ``nq == nv == 1``. Joints of the URDF that are not arm joints (grippers) are locked
later, at 0, by the model builder.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

from amex.core.errors import ConfigError
from amex.core.files import read_text
from amex.core.paths import cache_dir

#: A URDF inside the installed example-robot-data package: ``example-robot-data:<path>``.
ERD_PREFIX = "example-robot-data:"
#: A URDF this package generates: ``amex:<name>``.
GENERATED_PREFIX = "amex:"
_DROPPED = ("transmission", "gazebo")


@dataclass
class RobotConfig:
    """The arm. Empty fields take the catalogue's values for the robot ``name``.

    Attributes:
        name: a catalogue robot (``panda``, ``chain7``, ``ur5``, ...) or any label for your own
            URDF (then ``urdf``, ``joints``, ``tcp_frame`` and ``q0`` are required).
        urdf: the description: a file path, ``example-robot-data:<path in its robots/>`` or
            ``amex:<generated robot>``.
        joints: the arm joints, base to tip (revolute or continuous); other joints are locked.
        tcp_frame: link (or frame) whose origin is the tool centre point; its z-axis is the
            TCP axis of the task space.
        q0: start configuration, one angle per arm joint [rad].
        package_dirs: where ``package://`` mesh URLs resolve (default: the URDF's directory and
            its ancestors).
        torque_limit: symmetric joint torque limits [N m]; empty: the URDF's ``effort``.
        velocity_limit: joint speed limits [rad/s]; empty: the URDF's ``velocity``.
    """

    name: str = "panda"
    urdf: str = ""
    joints: list[str] = field(default_factory=list)
    tcp_frame: str = ""
    q0: list[float] = field(default_factory=list)
    package_dirs: list[str] = field(default_factory=list)
    torque_limit: list[float] = field(default_factory=list)
    velocity_limit: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class RobotDescription:
    """A fully specified robot: cleaned URDF text and the facts the builder needs.

    Attributes:
        name: the robot's label.
        urdf_path: the file the description came from (a generated file for ``amex:`` URDFs).
        urdf_text: the cleaned URDF (module notes).
        joints: arm joint names, base to tip.
        tcp_frame: the TCP frame's name.
        q0: start configuration [rad].
        package_dirs: where mesh URLs resolve.
        torque_limit: overrides, or empty.
        velocity_limit: overrides, or empty.
    """

    name: str
    urdf_path: str
    urdf_text: str
    joints: tuple[str, ...]
    tcp_frame: str
    q0: tuple[float, ...]
    package_dirs: tuple[str, ...]
    torque_limit: tuple[float, ...]
    velocity_limit: tuple[float, ...]


@cache
def erd_robots_dir() -> str:
    """The ``robots`` directory of the installed example-robot-data."""
    import example_robot_data

    return os.path.realpath(example_robot_data.getModelPath("panda_description"))


def _generated_path(name: str) -> str:
    """Write the generated URDF ``name`` to the cache directory once; its path."""
    from amex.robot.chain7 import chain7_urdf

    generators = {"chain7": chain7_urdf}
    if name not in generators:
        raise ConfigError.invalid("robot.urdf", GENERATED_PREFIX + name, sorted(generators))
    text = generators[name]()
    digest = hashlib.sha256(text.encode()).hexdigest()[:12]
    for base in (cache_dir() / "robots", Path(tempfile.gettempdir()) / "amex-robots"):
        path = base / f"{name}_{digest}.urdf"
        try:
            if not path.exists() or path.read_text() != text:
                base.mkdir(parents=True, exist_ok=True)
                fd, tmp = tempfile.mkstemp(dir=base, suffix=".urdf")
                with os.fdopen(fd, "w") as f:
                    f.write(text)
                os.replace(tmp, path)
            return str(path)
        except OSError:
            continue
    raise ConfigError(f"cannot write the generated URDF {name!r} to {cache_dir()} or /tmp")


def urdf_file(spec: str) -> str:
    """The file a ``robot.urdf`` value names (module :class:`RobotConfig`)."""
    if spec.startswith(ERD_PREFIX):
        return os.path.join(erd_robots_dir(), spec[len(ERD_PREFIX) :])
    if spec.startswith(GENERATED_PREFIX):
        return _generated_path(spec[len(GENERATED_PREFIX) :])
    return os.path.abspath(os.path.expanduser(spec))


def clean_urdf(text: str, source: str) -> str:
    """The URDF ``text`` cleaned as the module notes say.

    Raises:
        ConfigError: if the text is not a URDF.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as e:
        raise ConfigError(f"invalid robot.urdf={source!r}: not XML ({e})") from e
    if root.tag != "robot":
        raise ConfigError(f"invalid robot.urdf={source!r}: the root element is <{root.tag}>")
    for tag in _DROPPED:
        for element in root.findall(tag):
            root.remove(element)
    for joint in root.iter("joint"):
        for mimic in joint.findall("mimic"):
            joint.remove(mimic)
        if joint.get("type") == "continuous":
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = ET.SubElement(joint, "limit", {"effort": "0", "velocity": "0"})
            limit.set("lower", repr(-2.0 * math.pi))
            limit.set("upper", repr(2.0 * math.pi))
    return ET.tostring(root, encoding="unicode")


def urdf_joints(text: str) -> dict[str, tuple[str, str, str]]:
    """``{joint: (type, parent link, child link)}`` of a URDF text, in file order."""
    out = {}
    for joint in ET.fromstring(text).iter("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        out[joint.get("name", "")] = (
            joint.get("type", ""),
            "" if parent is None else parent.get("link", ""),
            "" if child is None else child.get("link", ""),
        )
    return out


def _package_dirs(path: str, given: list[str]) -> tuple[str, ...]:
    """``given``, else the URDF's directory and its ancestors (``package://`` resolves there)."""
    if given:
        return tuple(os.path.abspath(os.path.expanduser(d)) for d in given)
    dirs = []
    d = os.path.dirname(path)
    while d and d != os.path.dirname(d):
        dirs.append(d)
        d = os.path.dirname(d)
    return tuple(dirs)


def resolve(config: RobotConfig) -> RobotDescription:
    """The :class:`RobotDescription` of ``config``, the catalogue filling its empty fields.

    Raises:
        ConfigError: one line naming the bad value (unknown robot, unreadable or invalid URDF,
            missing joints, frame or start pose).
    """
    from amex.robot.catalogue import CATALOGUE

    known = CATALOGUE.get(config.name)
    urdf = config.urdf or (known.urdf if known else "")
    joints = list(config.joints) or (list(known.joints) if known else [])
    tcp = config.tcp_frame or (known.tcp_frame if known else "")
    q0 = list(config.q0) or (list(known.q0) if known else [])
    if not urdf:
        raise ConfigError(
            f"invalid robot={config.name!r}; valid: {', '.join(sorted(CATALOGUE))}, "
            "or your own arm with robot.urdf, robot.joints, robot.tcp_frame and robot.q0"
        )
    for key, value in (("joints", joints), ("tcp_frame", tcp), ("q0", q0)):
        if not value:
            raise ConfigError(f"robot.{key} is required for robot.urdf={urdf!r}")
    path = urdf_file(urdf)
    raw = read_text(path, "robot.urdf")
    return RobotDescription(
        name=config.name,
        urdf_path=path,
        urdf_text=clean_urdf(raw, urdf),
        joints=tuple(joints),
        tcp_frame=tcp,
        q0=tuple(float(x) for x in q0),
        package_dirs=_package_dirs(path, list(config.package_dirs)),
        torque_limit=tuple(float(x) for x in config.torque_limit),
        velocity_limit=tuple(float(x) for x in config.velocity_limit),
    )
