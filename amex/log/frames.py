"""The arm's link frames for Foxglove: one transform per URDF joint, parent/child = link names.

Foxglove's 3D panel poses a URDF from transforms between its links, looked up by the timestamp
inside each message. :class:`LinkTransforms` computes those transforms from the joint positions
and builds the ``foxglove.FrameTransforms`` message of one step.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3

if TYPE_CHECKING:
    from amex.robot import RobotModel

WORLD_FRAME = "world"
IDENTITY = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)


def sim_stamp(t: float) -> Timestamp:
    """Simulation time ``t`` [s] as a Foxglove timestamp."""
    ns = round(t * 1e9)
    return Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def vec(p: Any) -> Vector3:
    """A Foxglove Vector3 from 3 numbers."""
    x, y, z = (float(c) for c in p)
    return Vector3(x=x, y=y, z=z)


def _quat(R: np.ndarray) -> tuple[float, float, float, float]:
    """Rotation matrix -> unit quaternion (x, y, z, w)."""
    x, y, z, w = pin.Quaternion(np.asarray(R, dtype=float)).coeffs().tolist()
    return x, y, z, w


Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]


class LinkTransforms:
    """The transforms Foxglove needs to pose the URDF: one per URDF joint, between link frames.

    Joints of the Pinocchio model that rotate about their z-axis (all of the Panda's) take a
    closed form, ``P * Rz(q_j)`` with the joint placement P (about 2 us per joint in Python);
    any other joint falls back to ``oMf[parent]^-1 oMf[child]``. Links rigidly attached to the
    same Pinocchio joint (fixed URDF joints, the locked fingers) are constant and computed once.

    Attributes:
        root: the URDF's root link, placed at the world frame's origin.
        links: (parent, child) link names of every transform, in message order.
    """

    def __init__(self, robot: RobotModel) -> None:
        model = robot.model
        self._model = model
        self._data = model.createData()
        pin.framesForwardKinematics(model, self._data, robot.q0)
        pairs = _urdf_joints(robot.urdf_path)
        self.root = _root_link(pairs)
        revolute: list[tuple[str, str, int, Vec, Quat]] = []  # closed form: P * Rz(q[idx])
        constant: list[tuple[str, str, Vec, Quat]] = []
        self._generic: list[tuple[str, str, int, int]] = []  # (parent, child, fid_p, fid_c)
        for joint, parent, child in pairs:
            if not (model.existFrame(parent) and model.existFrame(child)):
                continue
            fp, fc = model.getFrameId(parent), model.getFrameId(child)
            frame_p, frame_c = model.frames[fp], model.frames[fc]
            if frame_p.parentJoint == frame_c.parentJoint:
                M = self._data.oMf[fp].actInv(self._data.oMf[fc])
                constant.append((parent, child, _xyz(M.translation), _quat(M.rotation)))
                continue
            jid = model.getJointId(joint) if model.existJointName(joint) else 0
            closed_form = (
                jid == frame_c.parentJoint
                and model.parents[jid] == frame_p.parentJoint
                and model.joints[jid].shortname() == "JointModelRZ"
                and frame_p.placement.isIdentity()
                and frame_c.placement.isIdentity()
            )
            if closed_form:
                P = model.jointPlacements[jid]
                idx = model.joints[jid].idx_q
                revolute.append((parent, child, idx, _xyz(P.translation), _quat(P.rotation)))
            else:
                self._generic.append((parent, child, fp, fc))
        self._revolute = [(p, c, i, tr, vec(tr), q) for p, c, i, tr, q in revolute]
        self._constant = [(p, c, tr, q, vec(tr), _quaternion(q)) for p, c, tr, q in constant]
        self.links: list[tuple[str, str]] = [
            (WORLD_FRAME, self.root),
            *((r[0], r[1]) for r in self._revolute),
            *((r[0], r[1]) for r in self._constant),
            *((r[0], r[1]) for r in self._generic),
        ]

    def constant_parts(self) -> list[tuple[str, str, Vec, Quat, int]] | None:
        """Every transform as (parent, child, translation, quaternion, joint index or -1).

        A transform with a joint index turns as ``P * Rz(q[index])`` (P: its translation and
        quaternion), one with -1 is constant; in message order. None if some transform takes
        the generic path (:meth:`message` then computes it by forward kinematics).
        """
        if self._generic:
            return None
        return [
            (WORLD_FRAME, self.root, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), -1),
            *((p, c, tr, quat, i) for p, c, i, tr, _, quat in self._revolute),
            *((p, c, tr, quat, -1) for p, c, tr, quat, _, _ in self._constant),
        ]

    def compute(self, q: np.ndarray) -> list[tuple[str, str, Vec, Quat]]:
        """The transforms at ``q``: (parent, child, translation [m], quaternion (x, y, z, w))."""
        out: list[tuple[str, str, Vec, Quat]] = [
            (WORLD_FRAME, self.root, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        ]
        qs = q.tolist()
        for parent, child, idx, tr, _, (x1, y1, z1, w1) in self._revolute:
            half = 0.5 * qs[idx]
            s, c = math.sin(half), math.cos(half)
            quat = (x1 * c + y1 * s, y1 * c - x1 * s, z1 * c + w1 * s, w1 * c - z1 * s)
            out.append((parent, child, tr, quat))
        for parent, child, tr, quat, _, _ in self._constant:
            out.append((parent, child, tr, quat))
        out.extend(self._compute_generic(q))
        return out

    def _compute_generic(self, q: np.ndarray) -> list[tuple[str, str, Vec, Quat]]:
        if not self._generic:
            return []
        pin.framesForwardKinematics(self._model, self._data, q)
        out = []
        for parent, child, fp, fc in self._generic:
            M = self._data.oMf[fp].actInv(self._data.oMf[fc])
            out.append((parent, child, _xyz(M.translation), _quat(M.rotation)))
        return out

    def message(self, q: np.ndarray, stamp: Timestamp) -> FrameTransforms:
        """The transforms at ``q`` as one FrameTransforms message (what :meth:`compute` gives)."""
        transforms = [
            FrameTransform(
                timestamp=stamp,
                parent_frame_id=WORLD_FRAME,
                child_frame_id=self.root,
                translation=Vector3(),
                rotation=IDENTITY,
            )
        ]
        qs = q.tolist()
        for parent, child, idx, _, tr, (x1, y1, z1, w1) in self._revolute:
            half = 0.5 * qs[idx]
            s, c = math.sin(half), math.cos(half)
            rot = Quaternion(
                x=x1 * c + y1 * s, y=y1 * c - x1 * s, z=z1 * c + w1 * s, w=w1 * c - z1 * s
            )
            transforms.append(
                FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=parent,
                    child_frame_id=child,
                    translation=tr,
                    rotation=rot,
                )
            )
        for parent, child, _, _, tr_c, q_c in self._constant:
            transforms.append(
                FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=parent,
                    child_frame_id=child,
                    translation=tr_c,
                    rotation=q_c,
                )
            )
        for parent, child, tr_g, q_g in self._compute_generic(q):
            transforms.append(
                FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=parent,
                    child_frame_id=child,
                    translation=vec(tr_g),
                    rotation=_quaternion(q_g),
                )
            )
        return FrameTransforms(transforms=transforms)


def _xyz(p: np.ndarray) -> Vec:
    x, y, z = p.tolist()
    return x, y, z


def _quaternion(q: Quat) -> Quaternion:
    x, y, z, w = q
    return Quaternion(x=x, y=y, z=z, w=w)


def _urdf_joints(urdf_path: str) -> list[tuple[str, str, str]]:
    """(joint, parent link, child link) of every joint in the URDF, in file order.

    Parsed once per file version (its size and modification time), not once per logged episode.
    """
    stat = os.stat(urdf_path)
    return list(_parsed_joints(urdf_path, stat.st_size, stat.st_mtime_ns))


@lru_cache(maxsize=8)
def _parsed_joints(urdf_path: str, size: int, mtime_ns: int) -> tuple[tuple[str, str, str], ...]:
    root = ET.parse(urdf_path).getroot()
    out = []
    for joint in root.iter("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is not None and child is not None:
            out.append((joint.get("name", ""), parent.get("link", ""), child.get("link", "")))
    return tuple(out)


def _root_link(pairs: list[tuple[str, str, str]]) -> str:
    children = {c for _, _, c in pairs}
    roots = [p for _, p, _ in pairs if p not in children]
    return roots[0] if roots else "panda_link0"
