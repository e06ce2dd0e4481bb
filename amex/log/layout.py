"""The Foxglove layout of an episode log, built for the log's own robot and channels.

The shipped template (``foxglove_layout.json``: a 3-D panel, plots of the distance to the goal,
the method's phase and the joint accelerations, the episode's result) is filled in from the log:
the URDF layer loads the log's robot (``robot`` metadata: name, URDF path, joint names) from a
URL (``amex-log view`` serves it) or a file path (Foxglove desktop), one plot line per joint, the
phase plot lists the method's numeric internals that the log has, and the 3-D panel shows only the
scene topics that carry messages (``/scene/plan`` exists only for methods that publish a plan).
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np

from amex.log.reader import LogData

TEMPLATE = Path(__file__).with_name("foxglove_layout.json")
URDF_LAYER = "robot-urdf"
SCENE_TOPICS = ("/scene/world", "/scene/reference", "/scene/path", "/scene/plan")
PHASE_KEYS = ("s", "phase", "phase_rate", "index")  # AMEX s, DMP x and its rate, Track's index
PHASE_LABELS = {"s": "AMEX s", "phase": "DMP x", "phase_rate": "DMP phase rate", "index": "index"}


def robot_of(data: LogData) -> dict[str, Any]:
    """The log's ``robot`` metadata (name, urdf_path, joint_names, links); {} for old logs."""
    return dict(data.metadata.get("robot", {}))


def _method_keys(data: LogData) -> list[str]:
    """Numeric fields of ``/method``, in first-seen order (``t`` left out)."""
    keys: dict[str, None] = {}
    for m in data.messages.get("/method", [])[:50]:
        if isinstance(m.data, dict):
            for k, v in m.data.items():
                if k != "t" and isinstance(v, (int, float)) and not isinstance(v, bool):
                    keys[k] = None
    return list(keys)


def _camera(data: LogData) -> dict[str, Any]:
    """Camera aimed at the robot's base and the scene (reference plan, goal, TCP path)."""
    parts = [np.zeros((1, 3)), data.reference_path()]
    parts += [data.series(t, "position") for t in ("/goal", "/tcp") if data.messages.get(t)]
    points = np.concatenate([p.reshape(-1, 3) for p in parts if np.size(p)])
    points = points[np.isfinite(points).all(axis=1)]
    center = (points.min(axis=0) + points.max(axis=0)) / 2
    radius = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))) / 2
    return {
        "target": [0, 0, 0],
        "targetOffset": [round(float(c), 3) for c in center],
        "distance": round(min(max(5.0 * radius, 2.0), 20.0), 2),
    }


def build_layout(
    data: LogData | None,
    *,
    urdf_url: str | None = None,
    urdf_path: str | None = None,
    robot: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The layout for ``data``; the URDF layer loads ``urdf_url`` if given, else a file path.

    Args:
        data: the log; None: a layout for any log of ``robot`` (every scene topic, every phase).
        urdf_url: URL of the robot description (what :mod:`amex.log.serve` serves).
        urdf_path: file path of the URDF for Foxglove desktop (default: the log's
            ``robot.urdf_path``).
        robot: name, urdf_path and joint_names (default: the log's ``robot`` metadata).
    """
    layout = json.loads(TEMPLATE.read_text())
    robot = robot if robot is not None else robot_of(data) if data is not None else {}
    name = str(robot.get("name", "robot"))
    panels = layout["configById"]
    scene = panels["3D!amex"]
    scene["foxglovePanelTitle"] = f"{name}, goal, obstacles, paths"
    if data is None:
        topics = list(SCENE_TOPICS)
    else:
        counts = {t: c.message_count for t, c in data.channels.items()}
        topics = [t for t in SCENE_TOPICS if counts.get(t)]
    scene["topics"] = {topic: {"visible": True} for topic in topics}
    layer = scene["layers"].pop("robot")
    layer.update({"instanceId": URDF_LAYER, "label": f"{name} (URDF)"})
    if urdf_url is not None:
        layer.update({"sourceType": "url", "url": urdf_url, "filePath": ""})
    else:
        path = urdf_path or str(robot.get("urdf_path", ""))
        layer.update({"sourceType": "filePath", "filePath": path, "url": ""})
    scene["layers"][URDF_LAYER] = layer
    if data is not None:
        scene["cameraState"].update(_camera(data))

    joints = [str(j) for j in robot.get("joint_names", [])]
    if not joints and data is not None:
        joints = [f"joint {i + 1}" for i in range(data.joints("position").shape[1])]
    line = panels["Plot!qdd"]["paths"][0]
    panels["Plot!qdd"]["paths"] = [
        {**copy.deepcopy(line), "value": f"/joint_states.joints[{i}].acceleration", "label": j}
        for i, j in enumerate(joints)
    ]
    phase = panels["Plot!phase"]
    keys = _method_keys(data) if data is not None else list(PHASE_KEYS)
    shown = [k for k in keys if k in PHASE_KEYS] or keys[:1]
    template = phase["paths"][0]
    phase["paths"] = [
        {
            **copy.deepcopy(template),
            "value": f"/method.{k}",
            "label": PHASE_LABELS.get(k, k),
            "enabled": k in shown,
        }
        for k in keys
    ]
    method = str(data.metadata.get("episode", {}).get("method", "")) if data is not None else ""
    phase["title"] = f"{method} internals".strip()
    return layout


def write_layout(layout: dict[str, Any], path: Path) -> Path:
    """Write ``layout`` as JSON (parent directories created); return ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(layout, indent=2) + "\n")
    return path
