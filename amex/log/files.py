"""Writing files: new files only, whole or not at all; failed log writes noticed.

Every output of ``amex-log`` (figures, tables, layouts) goes through :func:`write_new`: an
existing file is never replaced (:class:`~amex.core.errors.LogExistsError`), and a failed write
(a full disk) leaves nothing under the final name (:class:`~amex.core.errors.WriteError` naming
the file and the reason). An episode log is not refused but kept: an existing one is renamed
aside (:func:`set_aside`); :class:`WriteFailures` turns the MCAP writer's logged write failures
into one cause.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from amex.core.durable import create_new
from amex.core.errors import LogExistsError

log = logging.getLogger(__name__)


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


def set_aside(path: Path) -> Path:
    """Rename an existing ``path`` to the first free ``<stem>.old<n><suffixes>``; say so.

    A log is never overwritten: a rerun or a resumed run (whose interrupted episode left a
    ``.part`` file) keeps the earlier file next to the new one, with a warning.
    """
    name = path.name
    stem, dot, rest = name.partition(".")
    for n in range(1, 10_000):
        target = path.with_name(f"{stem}.old{n}{dot}{rest}")
        if not target.exists():
            os.rename(path, target)
            log.warning("log %s already existed; kept it as %s", path, target.name)
            return target
    raise LogExistsError(f"log file {path} exists and no free name is left to keep it")


class WriteFailures(logging.Filter):
    """Watches foxglove-sdk's log records for a failed write (e.g. a full disk).

    The SDK's writer does not raise when a write fails: it logs a warning per message from then
    on. Attached to its loggers while a log is open, this keeps the first failure's cause and
    swallows the rest, so that :class:`~amex.log.writer.EpisodeLogger` can stop with one error
    instead.
    """

    LOGGERS = ("foxglove.log_sink_set", "foxglove_py.mcap")

    def __init__(self) -> None:
        super().__init__()
        self.cause = ""

    def filter(self, record: logging.LogRecord) -> bool:
        """Keep the first write failure's cause and drop its record; pass any other record."""
        text = record.getMessage()
        if "McapError" not in text and "MCAP" not in text:
            return True
        if not self.cause:
            self.cause = failure_cause(text)
        return False

    def attach(self) -> None:
        """Watch the SDK's loggers (while a log is open)."""
        for name in self.LOGGERS:
            logging.getLogger(name).addFilter(self)

    def detach(self) -> None:
        """Stop watching them."""
        for name in self.LOGGERS:
            logging.getLogger(name).removeFilter(self)


def failure_cause(text: str) -> str:
    """The OS's words in a foxglove-sdk error (``No space left on device``), else the text."""
    for marker in ('message: "', "message: '"):
        if marker in text:
            return text.split(marker, 1)[1].split(marker[-1], 1)[0]
    return " ".join(text.split())[:200]
