"""What the study analyses share: finding a study's cells among the runs of its sweep.

A study is a sweep (``conf/study/<name>.yaml``, run by ``amex-run -m study=<name>``); its analysis
(:mod:`analysis.robustness`, :mod:`analysis.pr2`) reads the runs and runs no episode. A cell of
the report is a list of overrides on top of the study; its rows are those whose configuration
hash is the cell's (:func:`amex.experiment.store.config_hash`), wherever they are under the sweep
directory
and however many shards wrote them (:func:`analysis.table.load_runs` merges shards and refuses
overlaps and gaps). The command-line overrides the sweep ran with (``episodes=...``,
``max_time=...``) are read from its ``multirun.yaml``, so a cell's configuration is composed
exactly as its run was.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from amex.core.errors import AmexError

#: Keys of a sweep's command line that say which runs, not what they compute.
_NOT_CELL = ("shard", "shards", "log")


class StudyError(AmexError):
    """A study's runs are missing or incomplete; the message says which and how to fix it."""


def sweep_overrides(runs: Path, study: str, cell_keys: Sequence[str]) -> list[str]:
    """The overrides every cell of ``study`` shares: ``study=<study>`` and the sweep's own.

    Those of the command line recorded in ``runs/multirun.yaml`` (``episodes=2``,
    ``max_time=1``, ...), without sweeps and without the keys the cells set (``cell_keys``).
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    path = runs / "multirun.yaml"
    recorded: list[str] = []
    if path.exists():
        try:
            recorded = [str(o) for o in OmegaConf.load(path).hydra.overrides.task]
        except Exception as e:  # a damaged or foreign file
            raise StudyError(f"{path}: not the record of an amex-run sweep ({e})") from e
    skip = {*cell_keys, *_NOT_CELL, "study"}
    kept = [f"study={study}"]
    for override in OverridesParser.create().parse_overrides(recorded):
        key = override.key_or_group
        if override.is_sweep_override() or key in skip or override.is_hydra_override():
            continue
        kept.append(override.input_line or f"{key}={override.get_value_element_as_str()}")
    return kept


def cell_config(base: Sequence[str], cell: Sequence[str]) -> Any:
    """The validated :class:`~amex.experiment.config.RunConfig` of a cell (composed like its
    run)."""
    from amex.app.cli import load_config

    return load_config([*base, *cell])


def cell_rows(episodes: pd.DataFrame, config: Any, name: str, runs: Path) -> pd.DataFrame:
    """The rows of the cell whose configuration is ``config``: all its environments, in order.

    Raises:
        StudyError: the cell has no runs, or fewer environments than it asks for.
    """
    from amex.experiment.store import config_hash

    rows = episodes[
        (episodes.config_hash == config_hash(config)) & (episodes.env < config.episodes)
    ]
    rows = rows.sort_values("env", kind="stable")
    if len(rows) < config.episodes:
        what = "no runs" if rows.empty else f"{len(rows)} of its {config.episodes} environments"
        raise StudyError(
            f"{runs}: {what} of cell {name}; run the study's sweep (the same command resumes)"
        )
    return rows.copy()
