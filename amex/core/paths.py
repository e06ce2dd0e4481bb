"""Where amex keeps files between runs (the plan cache, generated robot descriptions)."""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path:
    """``$AMEX_CACHE_DIR``, else ``$XDG_CACHE_HOME/amex``, else ``~/.cache/amex``."""
    if "AMEX_CACHE_DIR" in os.environ:
        return Path(os.environ["AMEX_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "amex"
