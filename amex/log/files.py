"""Writing amex-log's outputs: new files only, whole or not at all.

Every output of ``amex-log`` (figures, tables, layouts) goes through :func:`write_new`: an
existing file is never replaced (:class:`~amex.core.errors.LogExistsError`), and a failed write
(a full disk) leaves nothing under the final name (:class:`~amex.core.errors.WriteError` naming
the file and the reason).
"""

from __future__ import annotations

from pathlib import Path

from amex.core.durable import create_new
from amex.core.errors import LogExistsError


def refuse_existing(*paths: Path) -> None:
    """Raise :class:`LogExistsError` for the first of ``paths`` that exists, before any work."""
    for path in paths:
        if path.exists() or path.is_symlink():
            raise LogExistsError(f"output file {path} already exists; not overwriting it")


def write_new(path: Path, data: bytes) -> None:
    """``data`` as the new file ``path`` (module notes); its directory is created."""
    refuse_existing(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        create_new(path, data)
    except FileExistsError:
        raise LogExistsError(f"output file {path} appeared meanwhile; not overwriting it") from None
