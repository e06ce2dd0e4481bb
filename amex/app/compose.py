"""Hydra's side of amex: where the configs are, their typed schemas, composing, and errors in words.

Configurations are composed with Hydra's public compose API from ``conf/`` (:data:`CONF_DIR`), the
typed schema of :class:`~amex.experiment.config.RunConfig` and of every method registered in
Hydra's ConfigStore. :func:`load_config` turns a list of overrides into a validated ``RunConfig``;
:func:`composed` gives the raw composition (Hydra's own part included) for the launch checks; any
error Hydra or OmegaConf raise becomes one line naming the bad value (:func:`explain`).
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from dataclasses import is_dataclass
from pathlib import Path
from typing import Any

from amex.core.errors import ConfigError, LaunchError, UsageError

CONF_DIR = str(Path(__file__).resolve().parents[2] / "conf")
PROG = "amex-run"


def shard_suffix(shard: Any, shards: Any) -> str:
    """``${amex.shard:${shard},${shards}}`` in directory names: ``_shard2of7``, or nothing."""
    try:
        count = int(shards)
    except (TypeError, ValueError):
        return f"_shard{shard}of{shards}"
    return f"_shard{shard}of{count}" if count != 1 else ""


def register_resolvers() -> None:
    """The ``amex.shard`` resolver of the directory names (idempotent)."""
    from omegaconf import OmegaConf

    if not OmegaConf.has_resolver("amex.shard"):
        OmegaConf.register_new_resolver("amex.shard", shard_suffix)


register_resolvers()  # also in sweep workers, which import this module with the job function


def register_schemas() -> None:
    """``RunConfig`` and every method's config dataclass in Hydra's ConfigStore (idempotent)."""
    from hydra.core.config_store import ConfigStore

    from amex.experiment.config import RunConfig
    from amex.methods import BUILTIN_METHODS, METHODS

    cs = ConfigStore.instance()
    cs.store(name="run_schema", node=RunConfig)
    for name, cls in METHODS.items():
        cs.store(group="method", name=f"schema_{name}", node=cls.config_class)
        if name not in BUILTIN_METHODS:  # a plugin: ``method=<name>`` is its dataclass's defaults
            cs.store(group="method", name=name, node=cls.config_class)


@contextlib.contextmanager
def initialized() -> Iterator[Any]:
    """Hydra initialized on :data:`CONF_DIR` for the block (yields its config loader).

    Hydra's global state is cleared before and after, so compositions never leak into each other.
    """
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    register_schemas()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
            yield GlobalHydra.instance().config_loader()
    finally:
        GlobalHydra.instance().clear()


def group_options(group: str) -> list[str]:
    """The options of a Hydra config group (``method``, ``hydra/launcher``, ``experiment``)."""
    try:
        with initialized() as loader:
            names = loader.get_group_options(group)
    except Exception:  # only for a message: never fail because of it
        return []
    return sorted(n for n in names if not n.startswith(("schema_", "_")))


def load_config(overrides: list[str]) -> Any:
    """Compose ``conf/config.yaml`` with ``overrides`` and return a validated ``RunConfig``."""
    from hydra import compose
    from omegaconf import OmegaConf

    from amex.experiment.config import validate

    for override in overrides:  # the typed schemas behind the methods are not methods
        key, _, value = override.lstrip("+~").partition("=")
        if key == "method" and value.startswith("schema_"):
            from amex.methods import METHODS

            raise UsageError(f"invalid method={value!r}; valid: {', '.join(sorted(METHODS))}")
    try:
        with initialized():
            cfg = compose(config_name="config", overrides=overrides)
        config: Any = OmegaConf.to_object(cfg)
    except ConfigError:
        raise
    except Exception as e:  # Hydra and OmegaConf raise many types for bad input
        raise UsageError(explain(e, overrides)) from e
    validate(config)
    return config


@contextlib.contextmanager
def composed(overrides: list[str], hydra_overrides: list[str]) -> Iterator[Any]:
    """The config the command line composes (Hydra's part included), read inside the block.

    Any error Hydra or OmegaConf raise, composing or in the block, becomes one
    :class:`LaunchError` naming the bad override.
    """
    from hydra import compose
    from hydra.core.utils import setup_globals

    setup_globals()  # the ${now:...} resolver of the default directories
    try:
        with initialized():
            cfg = compose(
                config_name="config",
                overrides=[*overrides, *hydra_overrides],
                return_hydra_config=True,
            )
        yield cfg
    except LaunchError:
        raise
    except Exception as e:  # Hydra and OmegaConf raise many types for bad input
        raise LaunchError(explain(e, overrides + hydra_overrides)) from e


def parse_overrides(overrides: list[str]) -> list[Any]:
    """Hydra's parse of ``overrides``; a bad one is a :class:`UsageError` naming it."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        return OverridesParser.create().parse_overrides(overrides)
    except Exception as e:  # Hydra's OverrideParseException and friends
        raise UsageError(f"invalid override: {explain(e, overrides)}") from e


def valid_keys(key: str, overrides: list[str]) -> str:
    """``valid keys of <node>: ...`` for the node an unknown dotted ``key`` was meant for."""
    from amex.experiment.config import RunConfig
    from amex.methods import METHODS

    chosen = [o.split("=", 1)[1] for o in overrides if o.startswith("method=")]
    method = chosen[-1] if chosen else "amex"
    node: Any = RunConfig()
    if method in METHODS:
        node.method = METHODS[method].config_class()
    parents = key.lstrip("+").split(".")[:-1]
    for name in parents:
        child = getattr(node, name, None)
        if not is_dataclass(child):
            break
        node = child
    else:
        names = [f for f in vars(node) if not f.startswith("_")]
        where = f" of {'.'.join(parents)}" if parents else ""
        return f"valid keys{where}: {', '.join(names)}"
    return f"valid keys: {', '.join(vars(RunConfig()))}"


def explain(error: Exception, overrides: list[str] | None = None) -> str:
    """Turn a Hydra/OmegaConf composition error into one line naming value and choices."""
    from amex.methods import METHODS
    from amex.sim.scenario import TASKS

    parts: list[str] = []
    seen: Exception | None = error
    while seen is not None and len(parts) < 10:  # the whole cause chain: Hydra wraps OmegaConf
        parts.append(str(seen))
        seen = seen.__cause__ or seen.__context__  # type: ignore[assignment]
    text = "\n".join(parts)
    m = re.search(r"Could not find '([\w/]+)/([^'/]*)'", text)
    if m:
        group, value = m.groups()
        if group == "method":
            return f"invalid method={value!r}; valid: {', '.join(sorted(METHODS))}"
        options = group_options(group)
        if options:
            return f"invalid {group}={value!r}; valid: {', '.join(options)}"
        return f"invalid {group}={value!r}; see `{PROG} --help` for the options of {group}"
    m = re.search(r"Could not override '([^']+)'", text) or re.search(
        r"Key '([^']+)' is not in struct", text
    )
    if m:
        return f"unknown config key {m.group(1)!r}; {valid_keys(m.group(1), overrides or [])}"
    m = re.search(r"Value '([^']*)' (?:of type '\w+' )?could not be converted to (\w+)", text)
    if m:
        key = re.search(r"full_key: (\S+)", text) or re.search(r"override ([\w.]+)=", text)
        name = key.group(1) if key else "value"
        if name == "task":
            return f"invalid task={m.group(1)!r}; valid: {', '.join(map(str, TASKS))}"
        return f"invalid {name}={m.group(1)!r}; valid: a value of type {m.group(2)}"
    first = text.strip().splitlines()[0] if text.strip() else type(error).__name__
    return first
