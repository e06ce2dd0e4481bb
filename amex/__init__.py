"""amex: Adaptive Motion Execution (Englert & Toussaint, IROS 2014) and its benchmark.

``amex.compose``, ``amex.run_episodes``, ``amex.run`` and ``amex.read_runs`` are the Python API
(:mod:`amex.app.api`), imported on first use.
"""

from typing import Any

from amex.core.version import __version__

_API = ("compose", "run_episodes", "run", "read_runs")


def __getattr__(name: str) -> Any:
    """The API's functions, imported on first use (``import amex`` stays light)."""
    if name in _API:
        from amex.app import api

        return getattr(api, name)
    raise AttributeError(f"module 'amex' has no attribute {name!r}")


__all__ = ["__version__", *_API]
