"""amex from Python: compose a configuration by name, run episodes or a whole run, read the rows.

The same configurations, checks and results as ``amex-run``, without its command line::

    import amex

    config = amex.compose("experiment=original", task=3, method="amex", episodes=5)
    rows = amex.run_episodes(config, envs=range(2))   # a pandas DataFrame, one row per episode
    rows = amex.run(config, "runs/mine")              # the whole run, resumable: episodes.csv

:func:`compose` takes Hydra overrides as text (``"experiment=original"``) and as keywords
(``task=3``; dotted keys as ``{"method.rate_max": 4.0}``), plus your own config directories
(``config_dirs=["conf"]``, as ``amex-run --config-dir``); it raises
:class:`~amex.core.errors.AmexError` subclasses naming a bad value, as the command line does.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from amex.app import compose as _compose
from amex.core.errors import ConfigError


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_text(v) for v in value) + "]"
    return str(value)


def compose(
    *overrides: str,
    config_dirs: Sequence[str | Path] = (),
    values: Mapping[str, Any] | None = None,
    **keywords: Any,
) -> Any:
    """A checked :class:`~amex.experiment.config.RunConfig` from overrides, as ``amex-run`` takes.

    Args:
        *overrides: Hydra overrides, e.g. ``"experiment=original"``, ``"method=cr"``.
        config_dirs: your config directories, searched before amex's own (``--config-dir``).
        values: more overrides by key, for dotted keys (``{"method.rate_max": 4.0}``).
        **keywords: overrides by key (``task=3``, ``method="amex"``, ``episodes=5``).

    Raises:
        ConfigError, UsageError: a bad value; the message names it and the valid choices.
    """
    items = [*overrides, *(f"{k}={_text(v)}" for k, v in {**(values or {}), **keywords}.items())]
    argv = [arg for d in config_dirs for arg in ("--config-dir", str(d))] + items
    previous = _compose.SOURCES
    try:
        plain = _compose.use_command_line(argv)
        config = _compose.load_config(plain)
    finally:
        _compose.SOURCES = previous
    from amex.experiment.runner import preflight

    preflight(config)
    return config


def run_episodes(
    config: Any, envs: Iterable[int] | None = None, log_dir: str | Path | None = None
) -> Any:
    """Run environments ``envs`` (default: all of the run's) and return their rows.

    Args:
        config: a :class:`~amex.experiment.config.RunConfig` (e.g. from :func:`compose`).
        envs: environment indices; each is the same scene for every method (paired).
        log_dir: write each episode's MCAP log there as ``episode_NNN.mcap``.

    Returns:
        A pandas DataFrame, one row per episode, with the columns of ``episodes.csv``
        (:mod:`amex.sim.metrics`) and ``log`` (the log's path, or empty).
    """
    import pandas as pd

    from amex.experiment.runner import prepare, run_setup, setup

    episodes = setup(config, prepare(config))
    rows = []
    for env in config.envs if envs is None else envs:
        if not (isinstance(env, int) and env >= 0):
            raise ConfigError.invalid("envs", env, "environment indices >= 0")
        path = None if log_dir is None else Path(log_dir) / f"episode_{env:03d}.mcap"
        row = run_setup(episodes, env, path).as_row()
        rows.append({**row, "log": "" if path is None else str(path)})
    return pd.DataFrame(rows)


def run(config: Any, run_dir: str | Path) -> Any:
    """The whole run into ``run_dir`` (``episodes.csv``, ``summary.json``; resumes); its rows."""
    from amex.experiment.runner import run as run_into

    run_into(config, Path(run_dir))
    return read_runs(run_dir)


def read_runs(path: str | Path) -> Any:
    """Every ``episodes.csv`` at or below ``path`` as one pandas DataFrame (column ``run``).

    Values are parsed as ``make table`` parses them (:func:`amex.experiment.store.parse_result`).
    """
    import pandas as pd

    from amex.experiment.store import HASH_COLUMNS, parse_result, read_rows

    base = Path(path)
    files = [base] if base.is_file() else sorted(base.rglob("episodes.csv"))
    if not files:
        raise ConfigError.invalid("path", str(path), "a run directory holding episodes.csv")
    rows = []
    for file in files:
        run = "." if file == base else str(file.parent.relative_to(base))
        for row in read_rows(file):
            hashes = {k: row[k] for k in HASH_COLUMNS if k in row}
            rows.append({**parse_result(row).as_row(), **hashes, "run": run})
    return pd.DataFrame(rows)


def with_values(config: Any, **values: Any) -> Any:
    """A copy of ``config`` with top-level fields replaced (``episodes=3``), checked again."""
    from amex.experiment.config import validate

    changed = replace(config, **values)
    validate(changed)
    return changed
