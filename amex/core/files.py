"""Reading a file a user named: regular files only, bounded in size, errors as one line.

A path that names a FIFO, a device (``/dev/zero``) or a directory would hang a reader or exhaust
memory; a description or mesh larger than its bound is no robot file.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from amex.core.errors import ConfigError

#: Largest robot description or mesh file read [bytes].
MAX_DESCRIPTION_BYTES = 64 * 1024 * 1024


def check_regular(path: str | Path, key: str, limit: int = MAX_DESCRIPTION_BYTES) -> int:
    """The size of ``path`` if it is a readable regular file of at most ``limit`` bytes.

    Raises:
        ConfigError: ``invalid <key>=<path>: ...; valid: ...`` naming what the path is.
    """
    try:
        info = os.stat(path)
    except OSError as e:
        raise ConfigError(f"invalid {key}={str(path)!r}: cannot read ({e.strerror})") from e
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
        kind = "a FIFO" if stat.S_ISFIFO(info.st_mode) else kind
        kind = "a device" if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode) else kind
        raise ConfigError(f"invalid {key}={str(path)!r}: {kind}; valid: a regular file")
    if info.st_size > limit:
        raise ConfigError(
            f"invalid {key}={str(path)!r}: {info.st_size:,} bytes; valid: a file of at most "
            f"{limit:,} bytes"
        )
    return info.st_size


def read_text(path: str | Path, key: str, limit: int = MAX_DESCRIPTION_BYTES) -> str:
    """The text of a regular file of at most ``limit`` bytes (:func:`check_regular`)."""
    check_regular(path, key, limit)
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
        if len(data) > limit:
            raise ConfigError(f"invalid {key}={str(path)!r}: grew beyond {limit:,} bytes")
        return data.decode()
    except (OSError, UnicodeDecodeError) as e:
        reason = getattr(e, "strerror", None) or str(e)
        raise ConfigError(f"invalid {key}={str(path)!r}: cannot read ({reason})") from e
