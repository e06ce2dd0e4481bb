"""The jobs of a ``-m`` sweep: the grids, every shard, and the longest first.

One function, :func:`sweep_jobs`, says which jobs a sweep runs, for the launching process's checks
(:mod:`amex.app.checks`), its progress bar (:mod:`amex.app.progress`) and the sweeper that launches
them (``hydra/sweeper=amex``, :mod:`hydra_plugins.amex_sweeper`), so the three always agree:

* ``hydra.sweeper.params`` and the command line make a Cartesian product, as with Hydra's basic
  sweeper (the command line wins for a key in both);
* ``hydra.sweeper.grids`` (``name: {key: values}``), if given, make one product per grid on top
  of the params, and the sweep runs their union, each job once: a study whose cells are not one
  product (a speed sweep and a noise sweep that share a cell) stays one sweep;
* a job that sets ``shards=K`` (on the command line, in a grid or in the config) but no
  ``shard`` becomes K jobs, ``shard=0..K-1``: ``amex-run -m task=3 method=cr shards=10`` runs
  the whole cell on ten jobs (:mod:`amex.experiment.shards`).

:func:`order_jobs` sorts them longest first by an estimate (:func:`estimate`: environments times
a measured cost per episode of the method on the task), which keeps every worker busy to the end
of a local sweep: a long job started last would otherwise run alone.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import Any

from amex.core.errors import UsageError

#: CPU seconds per episode (Panda, 100 Hz, seed 0): ``make paper``'s cells on the 2-core
#: development machine, 2026-12-04 (``cpu_time`` of their ``summary.json`` / 150, the mean of two
#: sweeps; task 0 as task 1; ``track``: DMP's less its outer steps, ~7 ms). Only the ratios
#: matter (:func:`order_jobs`; replaying those sweeps' cell times on two workers, this order ends
#: them 2.4 s apart, the figures of 2026-12-02 8.1 s, as CR's step became cheaper); methods not
#: listed cost like AMEX.
EPISODE_COST: dict[str, tuple[float, ...]] = {  # task 0, 1, 2, 3, 4
    "amex": (0.093, 0.093, 0.080, 0.150, 0.161),
    "dmp": (0.070, 0.070, 0.081, 0.111, 0.122),
    "dmp_ps": (0.070, 0.070, 0.081, 0.111, 0.122),
    "cr": (0.121, 0.121, 0.129, 0.365, 0.429),
    "track": (0.063, 0.063, 0.074, 0.104, 0.115),
}
_SHARD_KEYS = ("shard", "shards")


def _key(override: str) -> str:
    """The config key of ``key=value`` (without ``+``, ``++`` or ``~``)."""
    return override.split("=", 1)[0].lstrip("+~")


def job_value(job: Sequence[str], key: str, default: Any = None) -> Any:
    """The value (text) that ``job``'s overrides give ``key``, else ``default``."""
    found = default
    for override in job:
        if "=" in override and _key(override) == key:
            found = override.split("=", 1)[1]
    return found


def _override(key: str, value: Any) -> str:
    """``key=value`` as an override (YAML booleans as Hydra's ``true``/``false``)."""
    if isinstance(value, bool):
        value = "true" if value else "false"
    return f"{key}={value}"


def _product(overrides: list[str], config_loader: Any = None) -> list[list[str]]:
    """The Cartesian product of ``overrides`` (Hydra's basic sweeper's rule; later keys win).

    Choice and range sweeps expand by themselves; a ``glob(...)`` over a config group needs a
    ``config_loader`` (:func:`amex.app.compose.config_loader`) to know the group's options.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser = OverridesParser.create(config_loader=config_loader)
    values: dict[str, list[str]] = {}
    for override in parser.parse_overrides(overrides):
        key = override.get_key_element()
        if not override.is_sweep_override():
            values[key] = [f"{key}={override.get_value_element_as_str()}"]
        elif override.is_discrete_sweep():
            values[key] = [f"{key}={v}" for v in override.sweep_string_iterator()]
        else:
            raise UsageError(
                f"invalid sweep {override.input_line!r}; valid: a list a,b,c, range(start, stop"
                "[, step]), choice(...) or glob(...) over a config group (not an interval)"
            )
    return [list(job) for job in itertools.product(*values.values())]


def sweep_jobs(
    params: Mapping[str, Any] | None,
    grids: Mapping[str, Mapping[str, Any]] | None,
    arguments: Sequence[str],
    shards: int = 1,
    expand: bool = True,
    config_loader: Any = None,
) -> list[list[str]]:
    """Every job of a sweep, as override lists, in declaration order (module notes).

    Args:
        params: ``hydra.sweeper.params`` (key -> value or sweep, as text).
        grids: ``hydra.sweeper.grids`` (name -> params of one product), or None.
        arguments: the command line's task overrides (sweeps included, no ``hydra.*``).
        shards: the configured ``shards`` for jobs that do not set it.
        expand: run every shard of a job with ``shards > 1`` and no ``shard`` (as
            ``hydra/sweeper=amex`` does; Hydra's basic sweeper does not, nor has it grids).
        config_loader: Hydra's config loader, for ``glob(...)`` sweeps over config groups.

    Raises:
        hydra's OverrideParseException: a value that is not a valid override.
        UsageError: a sweep that is not a list of values (an interval).
    """
    base = [_override(k, v) for k, v in (params or {}).items()]
    products: list[list[str]] = []
    for grid in grids.values() if grids else [{}]:
        extra = [_override(k, v) for k, v in (grid or {}).items()]
        products += _product([*base, *extra, *arguments], config_loader)
    jobs: list[list[str]] = []
    seen: set[tuple[str, ...]] = set()
    for job in products:
        count = int(job_value(job, "shards", shards))
        expanded = [job]
        if expand and job_value(job, "shard") is None and count > 1:
            expanded = [[*job, f"shard={i}"] for i in range(count)]
        for one in expanded:
            key = tuple(sorted(one))
            if key not in seen:
                seen.add(key)
                jobs.append(one)
    return jobs


def estimate(job: Sequence[str], defaults: Mapping[str, Any]) -> float:
    """Estimated CPU seconds of ``job``: its environments times the method's cost on the task.

    ``defaults`` holds the configured ``task``, ``method`` (name), ``episodes``, ``shards`` and
    ``outer_hz`` for jobs that do not override them. CR's cost scales with the outer rate (one
    optimization per outer step); the others' is dominated by the 1 kHz inner loop.
    """

    def get(key: str) -> Any:
        return job_value(job, key, defaults.get(key))

    try:
        task, episodes = int(get("task")), int(get("episodes"))
        shards, shard = int(get("shards") or 1), int(get("shard") or 0)
        outer_hz = float(get("outer_hz") or 100.0)
    except (TypeError, ValueError):
        return 0.0
    method = str(get("method"))
    costs = EPISODE_COST.get(method, EPISODE_COST["amex"])
    cost = costs[task] if 0 <= task < len(costs) else max(costs)
    if method == "cr" and math.isfinite(outer_hz) and outer_hz > 0:
        fixed = EPISODE_COST["track"][task] if 0 <= task < 5 else 0.0  # what does not replan
        cost = fixed + (cost - fixed) * outer_hz / 100.0
    return len(range(shard, episodes, max(shards, 1))) * cost


def order_jobs(jobs: list[list[str]], defaults: Mapping[str, Any]) -> list[list[str]]:
    """``jobs`` sorted longest first by :func:`estimate` (ties keep their order)."""
    return sorted(jobs, key=lambda job: -estimate(job, defaults))


def job_defaults(config: Any) -> dict[str, Any]:
    """The values :func:`estimate` needs from a composed config (an OmegaConf node)."""
    method = config.get("method") or {}
    return {
        "task": config.get("task"),
        "method": method.get("name") if hasattr(method, "get") else None,
        "episodes": config.get("episodes"),
        "shards": config.get("shards"),
        "outer_hz": config.get("outer_hz"),
    }


def is_ours(sweeper: Any) -> bool:
    """Whether a ``hydra.sweeper`` node is ``hydra/sweeper=amex`` (grids, shards, order)."""
    return str(sweeper.get("_target_", "")).endswith("amex_sweeper.AmexSweeper")
