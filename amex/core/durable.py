"""The one write path for files a run must not lose or tear: appends, replacements, new files.

Every write goes through :func:`write_all`, which repeats ``os.write`` until the OS has taken
every byte and raises :class:`WriteError` when it takes none or fails (a full disk, a file-size
limit, an I/O error). Built on it:

* :func:`append_durably`: one record appended to a file and fsynced; when the write or the fsync
  fails the file is cut back to its length before, so it never holds a torn record.
* :func:`replace_durably`: a whole file written next to the target, fsynced, then renamed over it;
  on failure the target is left as it was and the temporary file removed.
* :func:`create_new`: like :func:`replace_durably`, but an existing file is never overwritten.

:class:`RunLock` is the run directory's lock: an ``flock`` held while a run writes, which the
kernel releases when the process ends however it ends, so a crash cannot leave it stuck.

None of them follows a symbolic link at the final component of the path it writes: the lock file
and appended files are opened with ``O_NOFOLLOW`` (and must be regular files), a replaced or new
file's name is checked with ``lstat`` just before the rename (which would replace a link, never
write through it), and temporary files are created with ``O_EXCL``. A link there is refused with
one :class:`WriteError` naming the file and where the link points, and nothing is written: a
link planted in a run directory cannot make amex truncate or overwrite another file. Links in the
directories above the file are followed as usual (a run directory may live behind one).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import secrets
import socket
import stat
import time
from pathlib import Path

from amex.core.errors import LockedError, WriteError

LOCK_NAME = ".amex-run.lock"
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)  # POSIX; without it the lstat checks below remain


def _reason(error: OSError) -> str:
    return error.strerror or str(error)


def _link_refusal(path: Path | str) -> WriteError:
    try:
        target = os.readlink(path)
    except OSError:
        target = "?"
    return WriteError(
        path,
        f"it is a symbolic link (to {target}); amex never writes through a link: "
        "remove it or choose another directory",
    )


def refuse_link(path: Path | str) -> None:
    """Raise :class:`WriteError` if ``path`` is a symbolic link (module notes); else nothing."""
    if os.path.islink(path):
        raise _link_refusal(path)


def _open_no_link(path: Path | str, flags: int, mode: int = 0o644) -> int:
    """``os.open`` that refuses a link at the final component and anything but a regular file.

    Raises:
        WriteError: the open failed, ``path`` is a symbolic link or not a regular file.
    """
    try:
        fd = os.open(path, flags | _NOFOLLOW, mode)
    except OSError as e:
        if e.errno in (errno.ELOOP, errno.EMLINK) and os.path.islink(path):
            raise _link_refusal(path) from e
        raise WriteError(path, _reason(e)) from e
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise WriteError(path, "not a regular file; amex writes only regular files")
    return fd


def write_all(fd: int, data: bytes, path: Path | str) -> None:
    """Write all of ``data`` to ``fd``, continuing after short writes.

    Raises:
        WriteError: the OS accepted no bytes (a full disk) or reported an error.
    """
    view = memoryview(data)
    while len(view):
        try:
            n = os.write(fd, view)
        except OSError as e:
            raise WriteError(path, _reason(e)) from e
        if n <= 0:
            raise WriteError(path, f"the disk took no more bytes ({len(view)} left unwritten)")
        view = view[n:]


def _fsync(fd: int, path: Path | str) -> None:
    try:
        os.fsync(fd)
    except OSError as e:
        raise WriteError(path, _reason(e)) from e


def append_durably(path: Path, data: bytes) -> None:
    """Append ``data`` to the existing file ``path`` and fsync; all of it or none of it.

    Raises:
        WriteError: the record could not be written; the file is cut back to its old length.
    """
    fd = _open_no_link(path, os.O_WRONLY | os.O_APPEND)
    try:
        start = os.fstat(fd).st_size
        try:
            write_all(fd, data, path)
            _fsync(fd, path)
        except WriteError:
            with contextlib.suppress(OSError):  # else the reader drops the torn last line
                os.ftruncate(fd, start)
                os.fsync(fd)
            raise
    finally:
        os.close(fd)


def _write_temporary(path: Path, data: bytes) -> Path:
    """``data`` in a new fsynced file beside ``path``; removed again if anything fails.

    The temporary name is new (``O_EXCL``, a random part): nothing that exists is written.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o644)
    except OSError as e:
        raise WriteError(path, _reason(e)) from e
    try:
        write_all(fd, data, path)
        _fsync(fd, path)
    except WriteError:
        os.close(fd)
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    os.close(fd)
    return tmp


def _sync_directory(directory: Path) -> None:
    with contextlib.suppress(OSError):  # not every file system can fsync a directory
        fd = os.open(directory, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def replace_durably(path: Path, data: bytes) -> None:
    """Write ``data`` as the new content of ``path``, atomically (temporary file, rename).

    Raises:
        WriteError: nothing was replaced; ``path`` keeps its old content (or stays absent), also
            when ``path`` is a symbolic link (module notes).
    """
    refuse_link(path)
    tmp = _write_temporary(path, data)
    try:
        refuse_link(path)  # again, just before the rename (which would replace, not follow)
        os.replace(tmp, path)
    except OSError as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise WriteError(path, _reason(e)) from e
    _sync_directory(path.parent)


def create_new(path: Path, data: bytes) -> None:
    """Write ``data`` as the new file ``path``, atomically; an existing file is never replaced.

    Raises:
        FileExistsError: ``path`` exists (checked atomically, at the final link).
        WriteError: the file could not be written; nothing is left behind.
    """
    if os.path.lexists(path):
        raise FileExistsError(errno.EEXIST, "file exists, not overwriting it", str(path))
    publish_new(_write_temporary(path, data), path)  # the link fails if path appeared meanwhile


#: The run locks this process holds: lock file -> (pid, fd, holds); the pid tells a forked copy.
_HELD: dict[str, tuple[int, int, int]] = {}


class RunLock:
    """Exclusive lock of a run directory while a run writes into it (``flock``).

    The lock file ``.amex-run.lock`` stays; the lock itself dies with its process, however the
    process ends (exit, exception, SIGKILL), so no stale lock is ever left to clear by hand.

    Args:
        directory: the run directory (must exist).
    """

    def __init__(self, directory: Path) -> None:
        self.path = directory / LOCK_NAME
        self._fd: int | None = None
        self._nested = False

    def acquire(self) -> RunLock:
        """Take the lock, or raise :class:`LockedError` naming its holder (no waiting).

        Re-entrant within a process: ``amex-run`` takes a run's lock before Hydra writes
        anything into the directory, and the run takes it again (a no-op) when it starts.

        Raises:
            LockedError: another process holds it.
            WriteError: the lock file cannot be opened, or it is a symbolic link or not a
                regular file (it is neither followed nor changed).
        """
        key = os.path.realpath(self.path)
        held = _HELD.get(key)
        if held is not None and held[0] == os.getpid():  # this process holds it already
            _HELD[key] = (held[0], held[1], held[2] + 1)
            self._nested = True
            return self
        fd = _open_no_link(self.path, os.O_RDWR | os.O_CREAT)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip()
            os.close(fd)
            raise LockedError(
                f"another amex-run is writing into {self.path.parent} ({holder or 'unknown'}); "
                "wait for it to finish or choose another hydra.run.dir / hydra.sweep.dir"
            ) from None
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        with contextlib.suppress(OSError):  # who holds it is for messages only (a full disk)
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()} since {stamp}".encode(), 0)
        self._fd = fd
        _HELD[key] = (os.getpid(), fd, 1)
        return self

    def release(self) -> None:
        """Give the lock up (idempotent); a nested hold only counts down."""
        key = os.path.realpath(self.path)
        if self._nested:
            self._nested = False
            pid, fd, count = _HELD[key]
            _HELD[key] = (pid, fd, count - 1)
            return
        if self._fd is not None:
            _HELD.pop(key, None)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()

    @staticmethod
    def holder(directory: Path) -> str | None:
        """Who holds the lock of ``directory`` now (None if nobody); never creates anything."""
        path = directory / LOCK_NAME
        try:  # a link is nobody's lock (acquire refuses it)
            fd = os.open(path, os.O_RDONLY | _NOFOLLOW | os.O_NONBLOCK)
        except OSError:
            return None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return os.pread(fd, 200, 0).decode(errors="replace").strip() or "unknown"
        finally:
            os.close(fd)
        return None


def publish_new(tmp: Path, path: Path) -> None:
    """Give the finished file ``tmp`` its final name ``path``, never replacing a file there.

    For outputs written by other libraries (a film, an image): they write ``tmp`` in the same
    directory; this links it to ``path`` atomically and removes ``tmp`` either way.

    Raises:
        FileExistsError: ``path`` exists (checked atomically, at the link).
        WriteError: the link could not be made.
    """
    try:
        os.link(tmp, path)  # fails if path exists
    except FileExistsError:
        raise FileExistsError(errno.EEXIST, "file exists, not overwriting it", str(path)) from None
    except OSError as e:
        raise WriteError(path, _reason(e)) from e
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()
    _sync_directory(path.parent)
