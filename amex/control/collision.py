"""Arm-to-obstacle distances with coal, through Pinocchio's geometry model.

The arm's capsules (:attr:`amex.robot.RobotModel.capsules`) and the scene's spherical obstacles live
in one ``pin.GeometryModel`` with a collision pair (capsule, obstacle) for each combination, so the
distances of all pairs come from one C++ call (``pin.computeDistances``, coal's GJK/EPA and
analytic primitive tests). Obstacles are attached to the world and moved by :meth:`set_obstacles`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import coal
import numpy as np
import pinocchio as pin

from amex.robot import RobotModel


class Proximity(NamedTuple):
    """One arm-obstacle pair closer than the margin.

    Attributes:
        distance: signed distance between the two shapes (negative when penetrating) [m].
        normal: unit vector from the obstacle towards the arm, shape (3,).
        point: witness point on the arm, in the world frame, shape (3,) [m].
        joint_id: Pinocchio joint the arm shape moves with.
        obstacle: index of the obstacle.
        shape: index of the arm shape in :attr:`amex.robot.RobotModel.capsules`.
    """

    distance: float
    normal: np.ndarray
    point: np.ndarray
    joint_id: int
    obstacle: int
    shape: int = 0


class CollisionModel:
    """Capsule arm versus sphere obstacles.

    Args:
        robot: the arm.
        radii: radius of each obstacle sphere [m]; the number of obstacles is ``len(radii)``.
    """

    def __init__(self, robot: RobotModel, radii: Sequence[float] | np.ndarray) -> None:
        self.robot = robot
        self.radii = tuple(float(r) for r in radii)
        gm = pin.GeometryModel()
        for cap in robot.capsules:
            shape = (
                coal.Capsule(cap.radius, 2.0 * cap.half_length)
                if cap.half_length > 0
                else coal.Sphere(cap.radius)
            )
            gm.addGeometryObject(pin.GeometryObject(cap.name, cap.joint_id, cap.placement, shape))
        self.n_arm = len(robot.capsules)
        self._obstacle_ids = []
        for k, r in enumerate(self.radii):
            obj = pin.GeometryObject(f"obstacle_{k}", 0, pin.SE3.Identity(), coal.Sphere(r))
            self._obstacle_ids.append(gm.addGeometryObject(obj))
        for oid in self._obstacle_ids:
            for i in range(self.n_arm):
                gm.addCollisionPair(pin.CollisionPair(i, oid))
        self.geom_model = gm
        self.geom_data = gm.createData()
        self._pair_arm = [cp.first for cp in gm.collisionPairs]
        self._pair_obstacle = [self._obstacle_ids.index(cp.second) for cp in gm.collisionPairs]
        self._joint_of = [gm.geometryObjects[i].parentJoint for i in range(self.n_arm)]
        self._placements = [gm.geometryObjects[oid].placement for oid in self._obstacle_ids]

    @property
    def n_obstacles(self) -> int:
        """Number of obstacle spheres."""
        return len(self.radii)

    def set_obstacles(self, centers: np.ndarray) -> None:
        """Move the obstacle spheres to ``centers``, shape (n_obstacles, 3) [m]."""
        for k, oid in enumerate(self._obstacle_ids):
            self.geom_model.geometryObjects[oid].placement.translation = centers[k]

    def proximities(self, data: pin.Data, margin: float) -> list[Proximity]:
        """All arm-obstacle pairs closer than ``margin`` [m], from the joint placements in ``data``.

        ``data`` must hold current joint placements (``oMi``), as a :class:`RobotState` leaves it.
        Only the closest pair is read when it is farther than the margin (the common case).
        """
        if not self._obstacle_ids:
            return []
        gm, gd = self.geom_model, self.geom_data
        pin.updateGeometryPlacements(self.robot.model, data, gm, gd)
        closest = pin.computeDistances(gm, gd)
        results = gd.distanceResults
        if results[closest].min_distance >= margin:
            return []
        out = []
        for k, res in enumerate(results):
            d = res.min_distance
            if d >= margin:
                continue
            p_arm = np.array(res.getNearestPoint1())
            p_obs = np.array(res.getNearestPoint2())
            diff = p_arm - p_obs
            norm = float(np.sqrt(diff @ diff))
            if norm > 1e-9 and d > 0:
                normal = diff / norm
            else:  # touching or penetrating: push along the centre-to-point direction
                c = self._placements[self._pair_obstacle[k]].translation
                away = p_arm - c
                normal = away / max(float(np.sqrt(away @ away)), 1e-12)
            arm = self._pair_arm[k]
            obstacle = self._pair_obstacle[k]
            out.append(Proximity(d, normal, p_arm, self._joint_of[arm], obstacle, arm))
        return out

    def obstacle_center(self, k: int) -> np.ndarray:
        """Centre of obstacle sphere ``k`` in the world frame, shape (3,) [m]."""
        return self._placements[k].translation

    def min_distance(self, data: pin.Data) -> float:
        """Smallest arm-obstacle distance [m] (``inf`` without obstacles)."""
        if not self._obstacle_ids:
            return float("inf")
        pin.updateGeometryPlacements(self.robot.model, data, self.geom_model, self.geom_data)
        k = pin.computeDistances(self.geom_model, self.geom_data)
        return float(self.geom_data.distanceResults[k].min_distance)
