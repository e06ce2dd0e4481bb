"""What every log of a run shares: computed once per (robot, reference plan), not per episode.

The link transforms' constants, the protobuf blocks of ``/tf`` and ``/joint_states``
(:mod:`amex.log.wire`) and the ``/reference`` message (~2 ms of formatting for a 401-sample plan)
depend only on the robot and the plan, which a run holds for all its episodes. :func:`log_constants`
keeps the last few, keyed by the objects' identity (a run's robot and plan are never changed
once built; weak references, so a finished run's robot is not kept alive); the values are pure
functions of them, so which episode computed them first changes nothing in any log. Loggers of
one process share them: they are read only, but the generic path of
:meth:`~amex.log.frames.LinkTransforms.message` (no robot of the catalogue takes it) writes its
Pinocchio data, so loggers sharing a robot must not run in parallel threads.
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from amex.log import messages as M
from amex.log.frames import LinkTransforms
from amex.log.wire import StepEncoding, step_encoding

if TYPE_CHECKING:
    from amex.plan.reference import ReferencePlan
    from amex.robot import RobotModel

_KEEP = 2  # (robot, plan) pairs remembered


class LogConstants(NamedTuple):
    """The parts of a log that depend only on the robot and the reference plan.

    Attributes:
        links: the URDF's link transforms.
        joint_names: the joints' names, in the order of q.
        encoding: the constant parts of ``/tf`` and ``/joint_states``; None when some transform
            takes the generic path (the messages are then built as the SDK's objects).
        reference_json: the ``/reference`` message.
        robot_record: the ``robot`` metadata record (name, URDF, package directories, joint
            names, q0, the URDF's links), its values JSON texts.
    """

    links: LinkTransforms
    joint_names: list[str]
    encoding: StepEncoding | None
    reference_json: bytes
    robot_record: dict[str, str]


_CACHE: list[tuple[weakref.ref[Any], weakref.ref[Any], LogConstants]] = []


def log_constants(robot: RobotModel, plan: ReferencePlan) -> LogConstants:
    """The constants of the logs of ``robot`` following ``plan`` (module notes)."""
    for robot_ref, plan_ref, constants in _CACHE:
        if robot_ref() is robot and plan_ref() is plan:
            return constants
    constants = _compute(robot, plan)
    _CACHE.insert(0, (weakref.ref(robot), weakref.ref(plan), constants))
    del _CACHE[_KEEP:]
    return constants


def _compute(robot: RobotModel, plan: ReferencePlan) -> LogConstants:
    links = LinkTransforms(robot)
    joint_names = list(robot.joint_names)
    parts = links.constant_parts()
    encoding = (
        step_encoding(parts, joint_names)
        if parts is not None and len(joint_names) == robot.model.nq == robot.nv
        else None
    )
    reference = M.reference_json(np.asarray(plan.y), plan.dt, plan.duration)
    record = M.metadata_record(
        {
            "name": robot.name,
            "urdf_path": robot.urdf_path,
            "package_dirs": list(getattr(robot.description, "package_dirs", ()) or ()),
            "joint_names": joint_names,
            "q0": robot.q0,
            "links": [list(link) for link in links.links],
        }
    )
    return LogConstants(links, joint_names, encoding, reference, record)
