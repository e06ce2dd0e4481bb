"""Sharded runs: one (task, method) cell's environments split over several jobs, and merged again.

``shards=K shard=I`` makes a run execute only the environments ``I, I + K, I + 2K, ...`` below
``episodes`` (:func:`shard_envs`), into its own directory. Strided, not in blocks, so that every
shard gets its share of the hard environments (on Task 3 the goals behind the obstacle are
neighbours in the grid) and the shards of a cell take about equally long. Every environment is
seeded from ``(seed, task, env)`` alone and the two fields are not part of the configuration hash
(:mod:`amex.experiment.store`), so an environment's row is the same whichever shard runs it, and a
cell's
shards resume and tabulate like one run.

A sharded run leaves ``shard.json`` in its directory (:func:`write_spec`): which shard of how many
over how many environments. Whoever merges the rows (``make table``, the study analyses) checks
with :func:`check_cover` that the shards of one configuration hold every environment exactly once
and says in one line which shard is missing or which environment two directories both hold.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

from amex.core.durable import replace_durably
from amex.core.errors import ConfigError, ShardError

SHARD_JSON = "shard.json"




@dataclass(frozen=True)
class ShardSpec:
    """Which environments a sharded run executes.

    Attributes:
        shard: this run's index, 0 <= shard < shards.
        shards: how many runs share the environments.
        episodes: environments of the whole cell (0 .. episodes - 1).
    """

    shard: int
    shards: int
    episodes: int

    def __post_init__(self) -> None:
        if self.shards < 1 or int(self.shards) != self.shards:
            raise ConfigError.invalid("shards", self.shards, "an integer >= 1")
        if self.shards > self.episodes:
            raise ConfigError.invalid(
                "shards", self.shards, f"at most episodes = {self.episodes} (one each at least)"
            )
        if not 0 <= self.shard < self.shards or int(self.shard) != self.shard:
            raise ConfigError.invalid("shard", self.shard, f"an integer in 0..{self.shards - 1}")

    @property
    def envs(self) -> range:
        """The environments of this shard (see :func:`shard_envs`)."""
        return shard_envs(self.episodes, self.shards, self.shard)

    @property
    def label(self) -> str:
        """``shard 2 of 7``."""
        return f"shard {self.shard} of {self.shards}"


def shard_envs(episodes: int, shards: int = 1, shard: int = 0) -> range:
    """Environments ``shard, shard + shards, ...`` below ``episodes`` (all of them for 1 shard)."""
    return range(shard, episodes, shards)


def write_spec(run_dir: Path, spec: ShardSpec) -> None:
    """Record ``spec`` as ``run_dir/shard.json`` (replaced atomically)."""
    text = json.dumps(asdict(spec), sort_keys=True) + "\n"
    replace_durably(run_dir / SHARD_JSON, text.encode())


def read_spec(run_dir: Path) -> ShardSpec | None:
    """The shard a run directory holds, or None for an unsharded run.

    Raises:
        ShardError: ``shard.json`` exists but cannot be read.
    """
    path = run_dir / SHARD_JSON
    if not path.exists():
        return None
    try:
        values = json.loads(path.read_text())
        return ShardSpec(int(values["shard"]), int(values["shards"]), int(values["episodes"]))
    except (OSError, ValueError, KeyError, TypeError, ConfigError) as e:
        raise ShardError(f"{path}: not a shard description ({e})") from e


def _listing(values: Iterable[int], limit: int = 6) -> str:
    items = sorted(values)
    shown = ", ".join(map(str, items[:limit]))
    return shown + (f" (+{len(items) - limit} more)" if len(items) > limit else "")


def check_cover(what: str, files: Mapping[str, tuple[ShardSpec | None, set[int]]]) -> None:
    """Check that the runs of one configuration, some of them shards, hold each environment once.

    Args:
        what: how to name the configuration in a message (``task 3 cr``).
        files: per run directory, its shard (None: unsharded) and the environments its rows hold.

    Raises:
        ShardError: the runs mix shard counts or cell sizes, two of them hold the same
            environment (an overlap), or an environment of the cell is in none (a gap).
    """
    specs = {name: spec for name, (spec, _) in files.items() if spec is not None}
    if not specs:
        return  # unsharded runs only: a rerun elsewhere may repeat rows (identical, dropped)
    plain = sorted(name for name, (spec, _) in files.items() if spec is None)
    if plain:
        raise ShardError(
            f"{what}: sharded and unsharded runs of the same configuration ({plain[0]} and "
            f"{sorted(specs)[0]}); tabulate one of them (RUNS=<its directory>)"
        )
    layouts = {(s.shards, s.episodes) for s in specs.values()}
    if len(layouts) > 1:
        shown = ", ".join(f"shards={k} of {n} environments" for k, n in sorted(layouts))
        raise ShardError(f"{what}: shards of different splits ({shown}); keep one split")
    shards, episodes = layouts.pop()
    owner: dict[int, str] = {}
    for name in sorted(files):
        for env in sorted(files[name][1]):
            if env in owner:
                raise ShardError(
                    f"{what}: environment {env} is in two shards ({owner[env]} and {name}); "
                    "shards must not overlap"
                )
            owner[env] = name
    missing = sorted(set(range(episodes)) - set(owner))
    if missing:
        absent = sorted({env % shards for env in missing})
        present = {s.shard for s in specs.values()}
        runs = [f"shard {i} of {shards}" + ("" if i in present else " (no run)") for i in absent]
        raise ShardError(
            f"{what}: environments {_listing(missing)} of {episodes} are missing ("
            f"{_listing_text(runs)}); run the missing shards (the same command resumes)"
        )


def _listing_text(items: list[str], limit: int = 4) -> str:
    shown = ", ".join(items[:limit])
    return shown + (f" (+{len(items) - limit} more)" if len(items) > limit else "")
