"""The arm on the live page: its URDF's visual meshes in viser (``viser.extras.ViserUrdf``).

Mesh references are resolved like the logs' (:func:`amex.log.urdf.resolve_mesh`: ``package://``
through the robot's package directories, then the URDF's ancestors), so every robot of the
catalogue shows its own meshes (the Panda's Collada files keep their materials). A description
whose visuals cannot be loaded is shown with its collision shapes instead.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from amex.robot import RobotModel
from amex.robot.meshes import resolve_mesh


def load_urdf(robot: RobotModel, visual: bool = True) -> Any:
    """The robot's URDF as a ``yourdfpy.URDF`` with its visual (or collision) meshes loaded."""
    import yourdfpy

    path = Path(robot.urdf_path)
    package_dirs = list(getattr(robot.description, "package_dirs", ()) or ())

    def filename(fname: str) -> str:
        found = resolve_mesh(fname, path, package_dirs)
        return str(found) if found is not None else fname

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # trimesh's notes on Collada materials
        return yourdfpy.URDF.load(
            path,
            build_scene_graph=visual,
            load_meshes=visual,
            build_collision_scene_graph=not visual,
            load_collision_meshes=not visual,
            filename_handler=filename,
        )


class RobotView:
    """The arm in a viser scene under ``root``; :meth:`show` poses it.

    Args:
        server: the viser server.
        robot: the arm (its joint names map the configuration onto the URDF's joints).
        root: scene node of the arm.
    """

    def __init__(self, server: Any, robot: RobotModel, root: str = "/robot") -> None:
        from viser.extras import ViserUrdf

        try:
            urdf = load_urdf(robot, visual=True)
            self.view = ViserUrdf(server, urdf, root_node_name=root)
            self.meshes = "visual"
        except Exception:  # a description whose visuals do not load (a missing mesh, a format)
            urdf = load_urdf(robot, visual=False)
            self.view = ViserUrdf(
                server, urdf, root_node_name=root, load_meshes=False, load_collision_meshes=True
            )
            self.meshes = "collision"
        names = list(self.view.get_actuated_joint_names())
        self._index = np.array([names.index(n) if n in names else -1 for n in robot.joint_names])
        self._cfg = np.zeros(len(names))
        self._last: np.ndarray | None = None

    def show(self, q: np.ndarray) -> None:
        """Pose the arm at joint angles ``q`` (the robot's joints, shape (n,)) [rad]."""
        q = np.asarray(q, dtype=float)
        last = self._last
        if last is not None and len(q) == len(last) and np.max(np.abs(q - last)) < 1e-4:
            return
        valid = self._index >= 0
        self._cfg[self._index[valid]] = q[: len(self._index)][valid]
        self.view.update_cfg(self._cfg)
        self._last = q.copy()
