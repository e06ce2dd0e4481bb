"""Where a URDF's mesh references point: ``package://``, ``file://`` and relative paths.

One resolution for the robot's builder, the renderer and the log viewer
(:mod:`amex.log.urdf` restricts what it serves on top of it).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Sequence
from pathlib import Path
from urllib.parse import unquote, urlparse

from amex.core.errors import ConfigError
from amex.core.files import check_regular


def package_candidates(
    package: str, urdf_path: Path, package_dirs: Sequence[str | Path]
) -> Iterator[Path]:
    """The directories ``package://package/...`` may name, in lookup order."""
    base = urdf_path.parent
    roots = [Path(p) for p in package_dirs]
    roots += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    for root in [*roots, base, *base.resolve().parents]:
        if root.name == package:
            yield root
        yield root / package


def resolve_mesh(
    filename: str, urdf_path: Path, package_dirs: Sequence[str | Path] = ()
) -> Path | None:
    """The file a URDF mesh reference points to, or None if it is not on this machine.

    Args:
        filename: the mesh's ``filename`` attribute.
        urdf_path: the URDF it appears in (relative paths start there).
        package_dirs: directories searched first for ``package://`` URLs (the robot's own).
    """
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        for directory in package_candidates(package, urdf_path, package_dirs):
            if (directory / rest).is_file():
                return (directory / rest).resolve()
        return None
    if filename.startswith("file://"):
        filename = unquote(urlparse(filename).path)
    path = Path(filename)
    path = path if path.is_absolute() else urdf_path.parent / path
    return path.resolve() if path.is_file() else None


def mesh_path(filename: str, urdf_path: Path, package_dirs: Sequence[str | Path] = ()) -> Path:
    """The path a mesh reference names, whether or not a file is there."""
    if filename.startswith("package://"):
        package, _, rest = filename[len("package://") :].partition("/")
        candidates = list(package_candidates(package, urdf_path, package_dirs))
        found = next((d / rest for d in candidates if (d / rest).exists()), None)
        return found if found is not None else candidates[0] / rest
    if filename.startswith("file://"):
        filename = unquote(urlparse(filename).path)
    path = Path(filename)
    return path if path.is_absolute() else urdf_path.parent / path


def check_collision_meshes(
    urdf_text: str, urdf_path: Path, package_dirs: Sequence[str | Path] = ()
) -> None:
    """Refuse a description whose collision meshes are no regular files of a sane size.

    A mesh that is a FIFO or a device (``/dev/zero``) would hang the mesh loader, a huge one
    exhaust memory; a missing one is left to the loader, which names it.

    Raises:
        ConfigError: ``invalid robot.urdf=...: mesh ...`` naming the mesh and what it is.
    """
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError:
        return  # the loader reports a malformed description with its own words
    meshes = [m for c in root.iter("collision") for m in c.iter("mesh")]
    for mesh in meshes:
        path = mesh_path(mesh.get("filename", ""), urdf_path, package_dirs)
        if not (path.exists() or path.is_symlink()):
            continue
        try:
            check_regular(path, "robot mesh")
        except ConfigError as e:
            raise ConfigError(f"invalid robot.urdf={str(urdf_path)!r}: {e}") from None
