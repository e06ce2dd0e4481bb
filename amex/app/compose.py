"""Hydra's side of amex: where the configs are, their typed schemas, composing, and errors in words.

Configurations are composed with Hydra's public compose API from ``conf/`` (:data:`CONF_DIR`), the
typed schema of :class:`~amex.experiment.config.RunConfig` and of every method registered in
Hydra's ConfigStore. :func:`load_config` turns a list of overrides into a validated ``RunConfig``;
:func:`composed` gives the raw composition (Hydra's own part included) for the launch checks; any
error Hydra or OmegaConf raise becomes one line naming the bad value (:func:`explain`).

Over 400 lines on purpose: composing, the schemas it needs and the wording of its errors share
this process's config sources (SOURCES) and Hydra's initialization; split, the parts would import
each other.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Iterator
from dataclasses import dataclass, is_dataclass
from pathlib import Path
from typing import Any

from amex.core.errors import ConfigError, LaunchError, UsageError

PROG = "amex-run"


def packaged_conf() -> Path:
    """Amex's own configs: ``amex/conf`` of an installed wheel, else the checkout's ``conf/``.

    The repository keeps ``conf/`` at its top level; the wheel ships it inside the package
    (``pyproject.toml`` maps it to ``amex.conf``), where an editable install has none.
    """
    package = Path(__file__).resolve().parents[1]
    installed = package / "conf"
    return installed if (installed / "config.yaml").is_file() else package.parent / "conf"


CONF_DIR = str(packaged_conf())
#: Flags of Hydra's that take a value (the rest of the command line is overrides).
FLAGS_WITH_VALUE = {"--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd"}


@dataclass
class Sources:
    """Where this command's configs come from besides amex's own (:data:`CONF_DIR`).

    Attributes:
        dirs: the user's config directories, searched before amex's: ``--config-dir`` and the
            ``file://`` entries of a ``hydra.searchpath=[...]`` override, in that order.
        name: the primary config (``--config-name``; amex's ``config``).
    """

    dirs: tuple[str, ...] = ()
    name: str = "config"

    def overrides(self) -> list[str]:
        """The ``hydra.searchpath`` override that adds :attr:`dirs` to a composition."""
        if not self.dirs:
            return []
        return ["hydra.searchpath=[" + ",".join(f"file://{d}" for d in self.dirs) + "]"]

    def conf_dirs(self) -> list[Path]:
        """Every config directory, the user's first (what ``--help`` lists)."""
        return [*(Path(d) for d in self.dirs), Path(CONF_DIR)]


#: This process's sources (:func:`use_command_line`).
SOURCES = Sources()


def use_command_line(argv: list[str]) -> list[str]:
    """Take ``--config-dir``, ``--config-name`` and ``hydra.searchpath`` from ``argv``.

    Sets :data:`SOURCES` for every composition of this process and returns the overrides of
    ``argv`` (its arguments that are no flags nor flag values).

    Raises:
        UsageError: a ``--config-dir`` that is no directory, or ``--config-path`` (amex's
            primary config is its own; ``--config-dir`` adds yours to it).
    """
    global SOURCES
    dirs: list[str] = []
    name = "config"
    overrides: list[str] = []
    args = iter(argv)
    for arg in args:
        flag, eq, inline = arg.partition("=")
        if flag in FLAGS_WITH_VALUE:
            value = inline if eq else next(args, "")
            if flag in ("--config-dir", "-cd"):
                path = Path(value).expanduser().resolve()
                if not path.is_dir():
                    raise UsageError(
                        f"invalid --config-dir {value!r}: not a directory; valid: a directory "
                        "holding your experiment/, robot/, method/ or study/ configs"
                    )
                dirs.append(str(path))
            elif flag in ("--config-name", "-cn"):
                name = value.removesuffix(".yaml")
            else:
                raise UsageError(
                    f"invalid {flag} {value!r}; valid: --config-dir DIR, which adds your "
                    "configs to amex's (amex's primary config stays its own)"
                )
            continue
        if arg.startswith("-"):
            continue
        if arg.startswith("hydra.searchpath="):
            dirs += [d.removeprefix("file://") for d in _list_value(arg.split("=", 1)[1])]
        overrides.append(arg)
    SOURCES = Sources(tuple(dict.fromkeys(dirs)), name)
    return overrides


def _list_value(text: str) -> list[str]:
    """The items of a Hydra list value ``[a,b]`` (or a single value)."""
    inner = text.strip()
    if inner.startswith("[") and inner.endswith("]"):
        inner = inner[1:-1]
    return [item.strip().strip("'\"") for item in inner.split(",") if item.strip()]


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


#: The methods whose schemas this process has stored (:func:`register_schemas`).
_REGISTERED: list[tuple[str, ...]] = []


def register_schemas() -> None:
    """``RunConfig`` and every method's config dataclass in Hydra's ConfigStore (idempotent).

    Stored once per process and set of registered methods: building a structured config of
    every schema costs ~0.1 s of CPU, and every composition of the command line calls this.
    """
    import importlib

    from hydra.core.config_store import ConfigStore
    from hydra.core.plugins import Plugins

    from amex.experiment.config import RunConfig
    from amex.methods import BUILTIN_METHODS, METHODS

    # our sweeper (hydra/sweeper=amex): Hydra finds plugins by listing the hydra_plugins
    # namespace, which an editable install cannot list; importing the module registers its
    # config, Hydra's public register() the class (installed wheels are found either way)
    if _REGISTERED and _REGISTERED[-1] == tuple(METHODS):
        return
    plugin = importlib.import_module("hydra_plugins.amex_sweeper.amex_sweeper")
    Plugins.instance().register(plugin.AmexSweeper)
    cs = ConfigStore.instance()
    _store_joblib_launcher(cs)
    cs.store(name="run_schema", node=RunConfig)
    for name, cls in METHODS.items():
        cs.store(group="method", name=f"schema_{name}", node=cls.config_class)
        if name not in BUILTIN_METHODS:  # a plugin: ``method=<name>`` is its dataclass's defaults
            cs.store(group="method", name=name, node=cls.config_class)
    _REGISTERED.append(tuple(METHODS))


#: Seconds an idle joblib worker waits for a job before it exits (loky's default: 300). Within a
#: sweep the workers are never idle that long; after it, or once its launcher was killed, they go.
IDLE_WORKER_TIMEOUT = 10


def _store_joblib_launcher(cs: Any) -> None:
    """``hydra/launcher=joblib`` with ``idle_worker_timeout`` (:data:`IDLE_WORKER_TIMEOUT`).

    Replaces the joblib launcher plugin's own config node (imported first, so it cannot store
    its node over ours later); the launcher passes every field on to ``joblib.Parallel``.
    """
    from dataclasses import make_dataclass

    from hydra_plugins.hydra_joblib_launcher.config import JobLibLauncherConf

    node = make_dataclass(
        "AmexJobLibLauncherConf",
        [("idle_worker_timeout", int, IDLE_WORKER_TIMEOUT)],
        bases=(JobLibLauncherConf,),
    )
    cs.store(group="hydra/launcher", name="joblib", node=node, provider="joblib_launcher")


@contextlib.contextmanager
def initialized() -> Iterator[Any]:
    """Hydra initialized on :data:`CONF_DIR` for the block (yields its config loader).

    Hydra's global state is cleared before and after, so compositions never leak into each other.
    """
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from amex.app.launch import VERSION_BASE

    register_schemas()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=CONF_DIR, version_base=VERSION_BASE):
            yield GlobalHydra.instance().config_loader()
    finally:
        GlobalHydra.instance().clear()


def group_options(group: str) -> list[str]:
    """The options of a Hydra config group (``method``, ``hydra/launcher``, ``experiment``)."""
    try:
        with initialized() as loader:
            names = _options(loader, group, "")
    except Exception:  # only for a message: never fail because of it
        return []
    return sorted(n for n in names if not n.rpartition("/")[2].startswith(("schema_", "_")))


def _options(loader: Any, group: str, prefix: str) -> list[str]:
    """The options of ``group`` and of its subgroups (``ablation/1_harness``), recursively."""
    extra = SOURCES.overrides()
    names = [
        prefix + n
        for n in loader.get_group_options(group, config_name=SOURCES.name, overrides=extra)
    ]
    for sub in loader.list_groups(group):
        names += _options(loader, f"{group}/{sub}", f"{prefix}{sub}/")
    return names


def load_config(overrides: list[str]) -> Any:
    """Compose ``conf/config.yaml`` with ``overrides`` and return a validated ``RunConfig``."""
    from hydra import compose

    refuse_schema_methods(overrides)
    try:
        with initialized():
            cfg = compose(config_name=SOURCES.name, overrides=[*overrides, *SOURCES.overrides()])
        config = run_config(cfg)
    except ConfigError:
        raise
    except Exception as e:  # Hydra and OmegaConf raise many types for bad input
        raise UsageError(explain(e, overrides)) from e
    return validated(config)


def refuse_schema_methods(overrides: list[str]) -> None:
    """Raise :class:`UsageError` for ``method=schema_*``: the typed schemas are not methods."""
    for override in overrides:
        key, _, value = override.lstrip("+~").partition("=")
        if key == "method" and value.startswith("schema_"):
            from amex.methods import METHODS

            raise UsageError(f"invalid method={value!r}; valid: {', '.join(sorted(METHODS))}")


def run_config(cfg: Any) -> Any:
    """The ``RunConfig`` object of a composition, Hydra's part (if any) left out; not validated."""
    from omegaconf import OmegaConf, open_dict, read_write

    if "hydra" in cfg:
        cfg = cfg.copy()
        with read_write(cfg), open_dict(cfg):
            del cfg["hydra"]
    return OmegaConf.to_object(cfg)


def validated(config: Any) -> Any:
    """``config`` after :func:`amex.experiment.config.validate` (raises ConfigError)."""
    from amex.experiment.config import validate

    validate(config)
    return config


@contextlib.contextmanager
def composed(overrides: list[str], hydra_overrides: list[str], hydra: Any = None) -> Iterator[Any]:
    """The config the command line composes (Hydra's part included), read inside the block.

    ``hydra``: the ``Hydra`` of a single run (:func:`amex.app.launch.main_hydra`), whose
    composition the run then uses; else Hydra is initialized for this composition alone.
    Any error Hydra or OmegaConf raise, composing or in the block, becomes one
    :class:`LaunchError` naming the bad override.
    """
    from hydra import compose
    from hydra.core.utils import setup_globals

    setup_globals()  # the ${now:...} resolver of the default directories
    try:
        if hydra is not None:
            from amex.app.launch import compose_run

            cfg = compose_run(hydra, SOURCES.name, [*overrides, *hydra_overrides])
        else:
            with initialized():
                user = [o for o in hydra_overrides if not o.startswith("hydra.searchpath=")]
                cfg = compose(
                    config_name=SOURCES.name,
                    overrides=[*overrides, *user, *SOURCES.overrides()],
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
    broken = _broken_yaml(error)
    if broken:
        return broken
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


def _broken_yaml(error: BaseException) -> str:
    """``invalid YAML in <file>, line L, column C: <problem>`` if a config file does not parse.

    Hydra's YAML error names no file; the config directories are few, so they are parsed again
    to find the one that fails.
    """
    import yaml

    seen: BaseException | None = error
    while seen is not None and not isinstance(seen, yaml.YAMLError):
        seen = seen.__cause__ or seen.__context__
    if seen is None:
        return ""
    for conf_dir in SOURCES.conf_dirs():
        for path in sorted(conf_dir.rglob("*.yaml")):
            try:
                yaml.safe_load(path.read_text())
            except yaml.MarkedYAMLError as e:
                mark = e.problem_mark or e.context_mark
                where = f", line {mark.line + 1}, column {mark.column + 1}" if mark else ""
                problem = " ".join(str(e.problem or e.context or "").split())
                return f"invalid YAML in {path}{where}: {problem}"
            except (OSError, yaml.YAMLError):
                continue
    return f"invalid YAML in a config file: {' '.join(str(seen).split())}"
