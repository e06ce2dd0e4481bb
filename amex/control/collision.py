"""Arm-to-obstacle distances with coal, through Pinocchio's geometry model.

The arm's capsules (:attr:`amex.robot.RobotModel.capsules`) and the scene's spherical obstacles live
in one ``pin.GeometryModel`` with a collision pair (capsule, obstacle) for each combination, so the
distances of all pairs come from one C++ call (``pin.computeDistances``, coal's GJK/EPA and
analytic primitive tests). Obstacles are attached to the world and moved by :meth:`set_obstacles`.

At 1 kHz the controller reads coal's results without a Python call per pair: coal keeps them in
one C++ vector (``GeometryData.distanceResults``) that never moves while the geometry data lives,
so :attr:`CollisionModel.table` is a numpy view of it (one row per pair: distance, normal, the
witness points on the arm and on the obstacle, as :data:`TABLE_COLUMNS`), and
:attr:`CollisionModel.placements` a view of the geometry placements ``oMg`` (rotation, column
major, then translation). Both views are checked against coal's and Pinocchio's own accessors
when the model is built; where a library's memory layout differs, the model falls back to copying
through the accessors at every update (the same numbers, slower). :meth:`CollisionModel.update`
is the per-step entry; :meth:`CollisionModel.proximities` the readable one (and the oracle).
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import NamedTuple

import coal
import numpy as np
import pinocchio as pin

from amex.robot import RobotModel

#: Columns of :attr:`CollisionModel.table`: distance [m], coal's normal (3), witness point on the
#: arm (3) [m], witness point on the obstacle (3) [m].
TABLE_COLUMNS = ("distance", "nx", "ny", "nz", "ax", "ay", "az", "ox", "oy", "oz")


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
        self.centers = np.zeros((len(self.radii), 3))  # obstacle centres [m], as placed
        n_pairs = len(self._pair_arm)
        #: for each pair: the arm shape, the obstacle, and which joint columns move the arm shape
        self.pair_arm = np.array(self._pair_arm, dtype=np.int64)
        self.pair_obstacle = np.array(self._pair_obstacle, dtype=np.int64)
        self.support = np.zeros((n_pairs, robot.nv))
        model = robot.model
        for k, arm in enumerate(self._pair_arm):
            for joint in model.supports[self._joint_of[arm]].tolist()[1:]:
                idx, nv = model.joints[joint].idx_v, model.joints[joint].nv
                self.support[k, idx : idx + nv] = 1.0
        self._results = list(self.geom_data.distanceResults)  # live references into coal's vector
        self._placements_live = [self.geom_data.oMg[i] for i in range(gm.ngeoms)]
        self.table = np.zeros((n_pairs, len(TABLE_COLUMNS)))
        self.placements = np.zeros((gm.ngeoms, 12))
        self.zero_copy = False
        self._data: pin.Data | None = None
        self._updated_for: object = None  # the state whose distances the views hold
        self.closest_distance = float("inf")
        if n_pairs:
            self._map_views()

    @property
    def n_obstacles(self) -> int:
        """Number of obstacle spheres."""
        return len(self.radii)

    def set_obstacles(self, centers: np.ndarray) -> None:
        """Move the obstacle spheres to ``centers``, shape (n_obstacles, 3) [m]."""
        for k, oid in enumerate(self._obstacle_ids):
            self.geom_model.geometryObjects[oid].placement.translation = centers[k]
        if len(self._obstacle_ids):
            self.centers[:] = centers
        self._updated_for = None

    def _map_views(self) -> None:
        """Point :attr:`table` and :attr:`placements` at coal's and Pinocchio's memory, if it fits.

        The rows must lie at one stride and hold, at the offsets found from the normal's address,
        exactly what the accessors return after a real distance query; otherwise the copies stay.
        """
        model, gm, gd = self.robot.model, self.geom_model, self.geom_data
        data = model.createData()
        pin.forwardKinematics(model, data, self.robot.q0)
        pin.updateGeometryPlacements(model, data, gm, gd)
        pin.computeDistances(gm, gd)
        table = _strided_view(
            [r.normal for r in self._results], offset=-1, width=len(TABLE_COLUMNS)
        )
        placements = _strided_view([g.rotation for g in self._placements_live], 0, 12)
        if table is None or placements is None:
            return
        self._copy_views()
        if np.array_equal(table, self.table) and np.array_equal(placements, self.placements):
            self.table, self.placements, self.zero_copy = table, placements, True

    def _copy_views(self) -> None:
        """Fill :attr:`table` and :attr:`placements` through the libraries' accessors (slow)."""
        table, placements = self.table, self.placements
        for k, res in enumerate(self._results):
            table[k, 0] = res.min_distance
            table[k, 1:4] = res.normal
            table[k, 4:7] = res.getNearestPoint1()
            table[k, 7:10] = res.getNearestPoint2()
        for i, oMg in enumerate(self._placements_live):
            placements[i, :9] = oMg.rotation.ravel(order="F")
            placements[i, 9:] = oMg.translation

    def update(self, data: pin.Data, key: object = None) -> float:
        """Distances of every pair from the joint placements in ``data``; the smallest [m].

        Afterwards :attr:`table` and :attr:`placements` hold the results (module notes). With a
        ``key`` (the controller passes its :class:`~amex.control.state.RobotState`), a second call
        for the same key and obstacles returns at once.
        """
        if key is not None and key is self._updated_for:
            return self.closest_distance
        if not self._obstacle_ids:
            return float("inf")
        gm, gd = self.geom_model, self.geom_data
        pin.updateGeometryPlacements(self.robot.model, data, gm, gd)
        closest = pin.computeDistances(gm, gd)
        if not self.zero_copy:
            self._copy_views()
        self._updated_for = key
        self.closest_distance = d = float(self.table[closest, 0])
        return d

    def proximities(self, data: pin.Data, margin: float) -> list[Proximity]:
        """All arm-obstacle pairs closer than ``margin`` [m], from the joint placements in ``data``.

        ``data`` must hold current joint placements (``oMi``), as a :class:`RobotState` leaves it.
        Only the closest pair is read when it is farther than the margin (the common case).
        """
        if not self._obstacle_ids:
            return []
        gm, gd = self.geom_model, self.geom_data
        self._updated_for = None  # the views now hold this query's results
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

    def min_distance(self, data: pin.Data, key: object = None) -> float:
        """Smallest arm-obstacle distance [m] (``inf`` without obstacles); ``key``: see update."""
        return self.update(data, key)


def _strided_view(views: list[np.ndarray], offset: int, width: int) -> np.ndarray | None:
    """Rows of ``width`` doubles starting ``offset`` doubles from each view's data, or None.

    ``views`` are numpy views into the elements of one C++ vector (Eigen members of its
    elements); the rows are returned as one array over that memory when the elements lie at one
    stride that fits ``width`` doubles.
    """
    if not views or any(v.flags.owndata or v.dtype != np.float64 for v in views):
        return None
    addresses = [v.__array_interface__["data"][0] for v in views]
    start = addresses[0] + 8 * offset
    stride = addresses[1] - addresses[0] if len(addresses) > 1 else 8 * width
    if stride < 8 * width or stride % 8 or any(
        a - addresses[0] != k * stride for k, a in enumerate(addresses)
    ):
        return None
    n_doubles = stride // 8 * (len(views) - 1) + width
    flat = np.ctypeslib.as_array((ctypes.c_double * n_doubles).from_address(start))
    return np.lib.stride_tricks.as_strided(flat, (len(views), width), (stride, 8), writeable=False)
