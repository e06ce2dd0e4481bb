"""Which runs form one benchmark: equal scene hashes, and runs that differ only in ``seed``.

The scene hash (:func:`amex.experiment.hashes.scene_hash`) covers the seed, so each seed of a
sweep ``seed=0,1,2`` has its own. :func:`benchmark_ids` joins the scene hashes whose runs differ
in nothing but the seed, read from what the runs recorded:

* the configuration: each run's ``.hydra/config.yaml`` without ``seed`` (and without ``task``,
  ``method``, ``episodes``, ``log``, ``shards``, ``shard``, which the scene hash leaves out or
  which say which environments run) must be equal, key for key;
* the code: for every task and method configuration that two seeds both ran, the rows'
  ``code_hash`` must be equal (it covers all of amex that computes episodes, so equal code hashes
  of one method mean equal shared code too), and they must share at least one.

A run without ``.hydra/config.yaml`` (written by :func:`amex.experiment.runner.run` directly) or
rows without a code hash stay a benchmark of their own scene hash, as before. Within a benchmark
an environment is ``(seed, env)``: every seed's environments stay paired across methods.
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict
from functools import cache
from pathlib import Path

import pandas as pd

#: Keys of ``config.yaml`` that two runs of one benchmark may differ in (besides ``seed``).
NOT_SCENE = ("task", "method", "episodes", "log", "shards", "shard")


@cache
def recorded_config(file: str) -> dict | None:
    """The ``.hydra/config.yaml`` beside an ``episodes.csv`` (None: none, or unreadable)."""
    import yaml

    path = Path(file).parent / ".hydra" / "config.yaml"
    try:
        config = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return None
    return config if isinstance(config, dict) else None


def _key(config: dict, leave_out: tuple[str, ...]) -> str:
    # std_ddof 0 is what runs recorded before the option existed meant
    spec = {
        k: v
        for k, v in config.items()
        if k not in leave_out and not (k == "std_ddof" and v == 0)
    }
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def run_keys(file: str, config_hash: str) -> tuple[str | None, str]:
    """(the run's configuration without seed, task and method; with task and method) as keys.

    Without a recorded configuration: (None, ``config_hash``).
    """
    config = recorded_config(file)
    if config is None:
        return None, config_hash
    variant = ("seed", "episodes", "log", "shards", "shard")  # a shard is no variant of a cell
    return _key(config, ("seed", *NOT_SCENE)), _key(config, variant)


class _Unit:
    """The rows of one scene hash: their seed, configuration key and code per cell."""

    def __init__(self, rows: pd.DataFrame) -> None:
        self.seeds = frozenset(int(s) for s in rows.seed.unique())
        keys = set(rows.scene_key)
        self.key = keys.pop() if len(keys) == 1 else None
        self.code: dict[tuple[int, str], set[str]] = defaultdict(set)
        for (task, variant), g in rows.groupby(["task", "variant"]):
            self.code[(int(task), str(variant))] |= set(g.code_hash)

    def joins(self, other: _Unit) -> bool:
        """Whether ``other`` differs from this unit in the seed only (module notes)."""
        if self.key is None or self.key != other.key or self.seeds & other.seeds:
            return False
        shared = set(self.code) & set(other.code)
        if not shared:
            return False
        for cell in shared:
            codes = self.code[cell] | other.code[cell]
            if len(codes) != 1 or "" in codes:
                return False
        return True


def benchmark_ids(df: pd.DataFrame) -> pd.Series:
    """The benchmark of every row of ``df``: its scene hash, or one id for seeds joined.

    ``df`` needs ``file``, ``config_hash``, ``scene_hash``, ``code_hash``, ``task``, ``seed``;
    the columns ``scene_key`` and ``variant`` (:func:`run_keys`) are added to it.
    """
    keys = {(f, c): run_keys(f, c) for f, c in df[["file", "config_hash"]].drop_duplicates().values}
    pairs = [keys[(f, c)] for f, c in zip(df.file, df.config_hash, strict=True)]
    df["scene_key"] = [k[0] for k in pairs]
    df["variant"] = [k[1] for k in pairs]
    hashes = sorted(df.scene_hash.unique())
    units = {h: _Unit(df[df.scene_hash == h]) for h in hashes}
    parent = {h: h for h in hashes}

    def root(h: str) -> str:
        while parent[h] != h:
            h = parent[h]
        return h

    for i, a in enumerate(hashes):
        for b in hashes[i + 1 :]:
            ra, rb = root(a), root(b)
            if ra == rb:
                continue
            members_a = [h for h in hashes if root(h) == ra]
            members_b = [h for h in hashes if root(h) == rb]
            if all(units[x].joins(units[y]) for x in members_a for y in members_b):
                parent[rb] = ra
    groups: dict[str, list[str]] = defaultdict(list)
    for h in hashes:
        groups[root(h)].append(h)
    ids = {}
    for members in groups.values():
        name = members[0] if len(members) == 1 else _joined(members)
        ids.update({h: name for h in members})
    return df.scene_hash.map(ids)


def _joined(scene_hashes: list[str]) -> str:
    text = "+".join(sorted(scene_hashes))
    return "seeds-" + hashlib.sha256(text.encode()).hexdigest()[:10]
