"""What ``amex-log view`` serves: the log as opened at the start, texts, files opened per request.

Each resource answers one request with an :class:`Opened` (size, media type, reader), or raises
:class:`Refused` with the status to send. A file is opened without following a symbolic link,
never blocking (a FIFO or a device is refused) and only while it is the regular file it was; the
log is the file opened at the start (:class:`Snapshot`); :class:`Site` maps request paths to them.
"""

from __future__ import annotations

import mimetypes
import os
import stat
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http import HTTPStatus
from pathlib import Path
from typing import NamedTuple

from amex.core.errors import LogError

OPEN_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
MAX_STUDIO_FILE_BYTES = 256 << 20  # [bytes]
# make test-viewer installs it
STUDIO_DIR = Path(__file__).resolve().parents[2] / "tests" / "viewer"
STUDIO_FILES = (
    "index.html",
    "main.js",
    "node_modules/react/umd/react.production.min.js",
    "node_modules/react-dom/umd/react-dom.production.min.js",
)
STUDIO_TREES = ("node_modules/@foxglove/studio-base/assets/",)


class Refused(Exception):
    """A request answered with an error status instead."""

    def __init__(self, status: HTTPStatus, text: str, size: int | None = None) -> None:
        super().__init__(text)
        self.status, self.text, self.size = status, text, size


class Opened(NamedTuple):
    """A resource opened for one answer: its size, media type and a reader of byte ranges."""

    size: int  # [bytes]
    ctype: str  # its media type
    read: Callable[[int, int], bytes]  # (offset, count) -> at most count bytes


@dataclass(frozen=True)
class TextResource:
    """A generated answer (the URDF, the layout, the index)."""

    content: bytes
    ctype: str

    @contextmanager
    def opened(self) -> Iterator[Opened]:
        """The text, for one answer."""
        yield Opened(
            len(self.content), self.ctype, lambda offset, n: self.content[offset : offset + n]
        )


@dataclass(frozen=True)
class FileResource:
    """A file opened per request, never through a symbolic link, if it is a regular file.

    ``identity`` (device, inode, size, modification time) at the start, if given, must still be
    the file's: a file replaced or rewritten since is not served.
    """

    path: Path
    max_bytes: int  # [bytes]
    identity: tuple[int, ...] | None = None

    @contextmanager
    def opened(self) -> Iterator[Opened]:
        """The file, opened for one answer without following a link, if it is still itself."""
        try:
            fd = os.open(self.path, OPEN_FLAGS)
        except OSError:
            raise Refused(HTTPStatus.NOT_FOUND, f"{self.path.name}: no longer there") from None
        try:
            info = os.fstat(fd)
            same = self.identity in (None, file_identity(info))
            if not (stat.S_ISREG(info.st_mode) and same and info.st_size <= self.max_bytes):
                raise Refused(HTTPStatus.GONE, f"{self.path.name}: changed since the start")
            ctype = mimetypes.guess_type(self.path.name)[0] or "application/octet-stream"
            yield Opened(info.st_size, ctype, lambda offset, n: os.pread(fd, n, offset))
        finally:
            os.close(fd)


def file_identity(info: os.stat_result) -> tuple[int, ...]:
    """What tells a file from another or from its changed self: device, inode, size, mtime."""
    return info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns


class Snapshot:
    """The log, opened once: served as it was while unchanged (deleted too), else 410."""

    def __init__(self, path: Path) -> None:
        self.fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        info = os.fstat(self.fd)
        if not stat.S_ISREG(info.st_mode):
            os.close(self.fd)
            raise LogError(f"{path} is not a regular file; amex-log view serves log files")
        self.size, self.mtime_ns = info.st_size, info.st_mtime_ns

    @contextmanager
    def opened(self) -> Iterator[Opened]:
        """The log as opened at the start; :class:`Refused` (410) once it changed in place."""
        info = os.fstat(self.fd)
        if (info.st_size, info.st_mtime_ns) != (self.size, self.mtime_ns):
            raise Refused(
                HTTPStatus.GONE, "the log changed since amex-log view started; restart it"
            )
        yield Opened(
            self.size, "application/octet-stream", lambda offset, n: os.pread(self.fd, n, offset)
        )

    def close(self) -> None:
        """Close the log's file."""
        os.close(self.fd)


Resource = TextResource | FileResource | Snapshot


@dataclass
class Site:
    """What the server answers, by URL path: generated texts, files, and a Studio build."""

    resources: dict[str, Resource] = field(default_factory=dict)
    studio: Path | None = None  # resolved

    def find(self, path: str) -> Resource | None:
        """The resource at URL ``path``; None if there is none."""
        if path in self.resources:
            return self.resources[path]
        if self.studio is None or not path.startswith("/studio/"):
            return None
        relative = path[len("/studio/") :]
        if any(part in ("", ".", "..") for part in relative.split("/")):
            return None
        if relative not in STUDIO_FILES and not relative.startswith(STUDIO_TREES):
            return None
        target = (self.studio / relative).resolve()
        if not (target.is_relative_to(self.studio) and target.is_file()):
            return None
        return FileResource(target, MAX_STUDIO_FILE_BYTES)
