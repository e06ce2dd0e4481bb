"""A robot description a browser can load: the URDF with every mesh served over HTTP.

Foxglove's URDF layer fetches the URDF and its meshes with ``fetch``: a browser can read neither
a file path nor a ``package://`` URL. :func:`viewer_urdf` rewrites the URDF a log names (its
``robot.urdf_path`` metadata) so that every mesh is a URL under one base URL, and returns the files
to serve there. Mesh references are resolved the ROS way, for any robot: ``package://PKG/rest`` is
looked up in the directories on ``ROS_PACKAGE_PATH`` and then in every ancestor of the URDF's
directory (a folder named ``PKG``, or holding ``PKG/rest``); ``file://`` and plain paths are taken
relative to the URDF. A visual whose mesh cannot be found is replaced by the link's collision
shapes (the Panda's collision model is cylinders and spheres), so the arm is always drawn.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote, unquote, urlparse

from amex.core.errors import LogError


@dataclass(frozen=True)
class ViewerUrdf:
    """A URDF rewritten for a browser.

    Attributes:
        text: the URDF, every mesh ``filename`` a URL under the base URL.
        files: the mesh files to serve, by their path under the base URL (``meshes/0/link0.dae``).
        replaced: names of the links whose visual meshes were missing and were replaced by their
            collision shapes.
    """

    text: str
    files: dict[str, Path] = field(default_factory=dict)
    replaced: tuple[str, ...] = ()


def resolve_mesh(
    filename: str, urdf_path: Path, package_dirs: Sequence[str | Path] = ()
) -> Path | None:
    """The file a URDF mesh reference points to, or None if it is not on this machine.

    Args:
        filename: the mesh's ``filename`` attribute.
        urdf_path: the URDF it appears in (relative paths start there).
        package_dirs: directories searched first for ``package://`` URLs (the robot's own).
    """
    base = urdf_path.parent
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        roots = [Path(p) for p in package_dirs]
        roots += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
        for root in [*roots, base, *base.resolve().parents]:
            if root.name == package and (root / rest).is_file():
                return (root / rest).resolve()
            if (root / package / rest).is_file():
                return (root / package / rest).resolve()
        return None
    if filename.startswith("file://"):
        filename = unquote(urlparse(filename).path)
    path = Path(filename)
    path = path if path.is_absolute() else base / path
    return path.resolve() if path.is_file() else None


def viewer_urdf(
    urdf_path: Path | str, base_url: str, package_dirs: Sequence[str | Path] = ()
) -> ViewerUrdf:
    """The URDF at ``urdf_path`` with its meshes under ``base_url`` (see the module notes).

    Args:
        urdf_path: the robot's URDF file.
        base_url: absolute URL the meshes are served under, ending in ``/``.
        package_dirs: where ``package://`` URLs resolve first (the log's ``robot`` metadata).

    Raises:
        LogError: the URDF is missing or is not XML.
    """
    urdf_path = Path(urdf_path)
    try:
        root = ET.fromstring(urdf_path.read_text())
    except OSError as e:
        raise LogError(
            f"the log's robot description {urdf_path} is not on this machine ({e.strerror}); "
            "view the log where it was recorded, or install the robot's package"
        ) from e
    except ET.ParseError as e:
        raise LogError(f"the robot description {urdf_path} is not valid XML: {e}") from e
    files: dict[str, Path] = {}
    served: dict[Path, str] = {}
    replaced: list[str] = []

    def served_everything(element: ET.Element) -> bool:
        ok = True
        for mesh in element.iter("mesh"):
            filename = mesh.get("filename", "")
            if filename.startswith(base_url):
                continue
            path = resolve_mesh(filename, urdf_path, package_dirs)
            if path is None:
                ok = False
                continue
            if path not in served:
                served[path] = f"meshes/{len(served)}/{path.name}"
                files[served[path]] = path
            mesh.set("filename", base_url + quote(served[path]))
        return ok

    for link in root.iter("link"):
        collisions = [c for c in link.findall("collision") if served_everything(c)]
        for collision in link.findall("collision"):
            if collision not in collisions:
                link.remove(collision)
        visuals = link.findall("visual")
        if all(served_everything(v) for v in visuals):
            continue
        for visual in visuals:  # some mesh is missing: draw the collision shapes instead
            link.remove(visual)
        for collision in collisions:
            visual = ET.fromstring(ET.tostring(collision))
            visual.tag = "visual"
            link.append(visual)
        replaced.append(link.get("name", "?"))
    text = ET.tostring(root, encoding="unicode")
    return ViewerUrdf('<?xml version="1.0"?>\n' + text + "\n", files, tuple(replaced))
