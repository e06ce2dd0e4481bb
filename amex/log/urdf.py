"""A robot description a browser can load: the URDF with every mesh served over HTTP.

Foxglove's URDF layer fetches the URDF and its meshes with ``fetch``: a browser can read neither
a file path nor a ``package://`` URL. :func:`viewer_urdf` rewrites the URDF a log names (its
``robot.urdf_path`` metadata) so that every mesh is a URL under one base URL, and returns the files
to serve there. Mesh references are resolved the ROS way, for any robot: ``package://PKG/rest`` is
looked up in the directories on ``ROS_PACKAGE_PATH`` and then in every ancestor of the URDF's
directory (a folder named ``PKG``, or holding ``PKG/rest``); ``file://`` and plain paths are taken
relative to the URDF. A visual whose mesh cannot be found is replaced by the link's collision
shapes (the Panda's collision model is cylinders and spheres), so the arm is always drawn.

A log, and so the URDF it names, may come from someone else, and whatever is listed here is served
over HTTP: :func:`servable_mesh` lets through only mesh files (:data:`MESH_SUFFIXES`, regular
files of at most :data:`MAX_MESH_BYTES`) whose real path, symbolic links followed, lies inside the
package directory they were resolved in. A package directory is one holding a ``package.xml`` or
one the URDF itself lies in, never ``/``, the home directory or one of its ancestors; a
``file://`` or plain path must lie inside the URDF's own package (the nearest such directory
around it, else the URDF's directory). A refused mesh is drawn like a missing one, and listed in
:attr:`ViewerUrdf.refused`. The URDF is read only if it is a regular file of at most
:data:`MAX_URDF_BYTES` whose root element is ``<robot>``. ``docs/viewers-security.md`` says why.
"""

from __future__ import annotations

import os
import stat
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote, unquote, urlparse

from amex.core.errors import LogError
from amex.robot.meshes import package_candidates

MESH_SUFFIXES = (".dae", ".stl", ".obj", ".glb", ".gltf")  # what Foxglove's URDF layer loads
MAX_MESH_BYTES = 128 << 20  # [bytes] per mesh file
MAX_URDF_BYTES = 16 << 20  # [bytes]


@dataclass(frozen=True)
class ViewerUrdf:
    """A URDF rewritten for a browser.

    Attributes:
        text: the URDF, every mesh ``filename`` a URL under the base URL.
        files: the mesh files to serve, by their path under the base URL (``meshes/0/link0.dae``).
        replaced: names of the links whose visual meshes were missing or refused and were
            replaced by their collision shapes.
        refused: the mesh references found but not served, each with the reason.
    """

    text: str
    files: dict[str, Path] = field(default_factory=dict)
    replaced: tuple[str, ...] = ()
    refused: tuple[str, ...] = ()


def _too_wide(directory: Path) -> bool:
    """``/``, the home directory or one of its ancestors: no robot's package."""
    home = Path.home().resolve()
    return directory == Path(directory.anchor) or home.is_relative_to(directory)


def _is_package(directory: Path, urdf_dir: Path) -> bool:
    """Whether ``directory`` (resolved) may hold a robot's files (see the module notes)."""
    if _too_wide(directory):
        return False
    return urdf_dir.is_relative_to(directory) or (directory / "package.xml").is_file()


def _own_package(urdf_dir: Path) -> Path | None:
    """The URDF's package: the nearest directory around it holding ``package.xml``.

    Else the URDF's directory; None if that is too wide (:func:`_too_wide`).
    """
    for directory in [urdf_dir, *urdf_dir.parents]:
        if _too_wide(directory):
            break
        if (directory / "package.xml").is_file():
            return directory
    return None if _too_wide(urdf_dir) else urdf_dir


def _checked(path: Path, package: Path, filename: str) -> tuple[Path | None, str]:
    """``(real path, "")`` if the file at ``path`` may be served from ``package``."""
    try:
        real = path.resolve(strict=True)
        info = real.stat()
    except (OSError, RuntimeError):  # a missing file, a symbolic link loop
        return None, ""
    if not real.is_relative_to(package):
        return None, f"{filename}: outside the robot's package {package}"
    if real.suffix.lower() not in MESH_SUFFIXES:
        return None, f"{filename}: not a mesh file ({', '.join(MESH_SUFFIXES)})"
    if not stat.S_ISREG(info.st_mode):
        return None, f"{filename}: not a regular file"
    if info.st_size > MAX_MESH_BYTES:
        return None, f"{filename}: larger than {MAX_MESH_BYTES >> 20} MiB"
    return real, ""


def servable_mesh(
    filename: str, urdf_path: Path, package_dirs: Sequence[str | Path] = ()
) -> tuple[Path | None, str]:
    """The file a mesh reference names if it may be served (see the module notes).

    Args:
        filename: the mesh's ``filename`` attribute.
        urdf_path: the URDF it appears in.
        package_dirs: directories searched first for ``package://`` URLs.

    Returns:
        ``(path, "")`` for a servable mesh; ``(None, "")`` if there is no such file;
        ``(None, reason)`` if there is one but it is not served.
    """
    urdf_dir = urdf_path.resolve().parent
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        if package in ("", ".", "..") or "\\" in package:
            return None, f"{filename}: not a package name"
        for directory in package_candidates(package, urdf_path, package_dirs):
            if not (directory / rest).exists():
                continue
            directory = directory.resolve()
            if not _is_package(directory, urdf_dir):
                return None, f"{filename}: {directory} is not a robot package"
            return _checked(directory / rest, directory, filename)
        return None, ""
    path = Path(unquote(urlparse(filename).path) if filename.startswith("file://") else filename)
    path = path if path.is_absolute() else urdf_dir / path
    own = _own_package(urdf_dir)
    if own is None:
        exists = path.exists()
        return None, f"{filename}: the URDF's directory {urdf_dir} is no package" if exists else ""
    return _checked(path, own, filename)


def read_urdf(urdf_path: Path) -> ET.Element:
    """The root ``<robot>`` element of the URDF file at ``urdf_path``, read with bounds.

    Raises:
        LogError: the file is missing, not a regular file, too large, not XML or not a URDF.
    """
    try:
        fd = os.open(urdf_path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)  # a FIFO: no wait
    except OSError as e:
        raise LogError(
            f"the log's robot description {urdf_path} is not on this machine ({e.strerror}); "
            "view the log where it was recorded, or install the robot's package"
        ) from e
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise LogError(f"the log's robot description {urdf_path} is not a regular file")
        data = f.read(MAX_URDF_BYTES + 1)
    if len(data) > MAX_URDF_BYTES:
        raise LogError(
            f"the log's robot description {urdf_path} is larger than {MAX_URDF_BYTES >> 20} MiB"
        )
    try:
        root = ET.fromstring(data)
    except ET.ParseError as e:
        raise LogError(f"the robot description {urdf_path} is not valid XML: {e}") from e
    if root.tag != "robot":
        raise LogError(
            f"the log's robot description {urdf_path} is not a URDF: its root element is "
            f"<{root.tag}>, not <robot>"
        )
    return root


def viewer_urdf(
    urdf_path: Path | str, base_url: str, package_dirs: Sequence[str | Path] = ()
) -> ViewerUrdf:
    """The URDF at ``urdf_path`` with its meshes under ``base_url`` (see the module notes).

    Args:
        urdf_path: the robot's URDF file.
        base_url: absolute URL the meshes are served under, ending in ``/``.
        package_dirs: where ``package://`` URLs resolve first (the log's ``robot`` metadata).

    Raises:
        LogError: the URDF is missing, not a regular file, too large, not XML or not a URDF.
    """
    urdf_path = Path(urdf_path)
    root = read_urdf(urdf_path)
    files: dict[str, Path] = {}
    served: dict[Path, str] = {}
    replaced: list[str] = []
    refused: dict[str, None] = {}

    def served_everything(element: ET.Element) -> bool:
        ok = True
        for mesh in element.iter("mesh"):
            filename = mesh.get("filename", "")
            path, reason = servable_mesh(filename, urdf_path, package_dirs)
            if path is None:
                if reason:
                    refused[reason] = None
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
    return ViewerUrdf(
        '<?xml version="1.0"?>\n' + text + "\n", files, tuple(replaced), tuple(refused)
    )
