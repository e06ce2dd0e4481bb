"""The hashes of a run: which configuration and which code computed its episodes.

* :func:`config_hash`: everything that determines an episode: the configuration (task, method and
  its parameters, scenes, plan, controller, rates, seed; not ``episodes``, ``log``,
  ``log_compression``, ``shards`` or ``shard``, which say which environments a run executes and
  how it logs them, not what they compute) and the code (:func:`code_hash`). A run resumes by
  skipping the environments recorded under the same hash. The method's parameters are hashed in
  the scene's units (:mod:`amex.core.scaling`) and the robot's start pose as resolved from the
  catalogue, so a value written another way hashes the same; an option added later is left out
  while it has its neutral value (``_ADDED_OPTIONS``).
* :func:`scene_hash`: the same without task and method, and with only the code all methods share
  (amex without ``amex/methods/``): rows of different methods with equal scene hashes ran on
  identical environments, under one controller and one scoring (paired comparisons).
* :func:`code_hash`: a digest of the code that computes the episodes.

What the code hash promises. It covers (1) the bytes of every ``.py`` file of amex that an
episode's numbers pass through: all of ``amex/`` except :data:`NOT_RESULT_CODE` (the command line
and Hydra in ``app/``, the MCAP logs in ``log/``, Hydra's plugin shim, the YAML defaults, whose
values are hashed as configuration, and the modules that store rows, pick shards, find the cache
or colour figures); (2) the installed versions of the numerical packages
(:data:`NUMERIC_DISTRIBUTIONS`); (3) for a method from outside amex (a plugin), the bytes of its
class's module and the version of the distribution that ships it. So a resume after editing a
method, amex's simulation or controller, after ``pip install -U mujoco`` or a new version of a
plugin is refused with one line. It is conservative: any byte (a comment too) counts, and any
edit of ``amex/methods/`` orphans the runs of every method. It does not cover: other modules a
plugin imports, compiled code whose version string stays the same, the BLAS kernel the machine
picks (docs/reproducibility.md), and edits made after the process first computed the digest
(once per process, then cached: the code that runs is the code that was imported).
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import json
import sys
from dataclasses import asdict, dataclass
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

from amex.core.errors import ConfigError
from amex.core.version import __version__

#: Parts of ``amex/`` (paths relative to it) outside the code digest: they do not compute results.
NOT_RESULT_CODE = (
    "app/",
    "log/",
    "_plugins/",
    "conf/",
    "experiment/hashes.py",
    "experiment/store.py",
    "experiment/shards.py",
    "core/durable.py",
    "core/paths.py",
    "core/palette.py",
)
METHOD_CODE = "methods/"  # in the code hash, not in the scene hash's shared code
#: Distributions whose versions are part of the code digest: the numbers pass through them.
NUMERIC_DISTRIBUTIONS = (
    "numpy",
    "scipy",
    "numba",
    "mujoco",
    "pin",
    "coal",
    "example-robot-data",
    "example-robot-data-loaders",
)
_AMEX_ROOT = Path(__file__).resolve().parents[1]  # the amex package
# which rows, not what they hold; std_ddof: how the summary aggregates them
_NOT_RESULTS = ("episodes", "log", "log_compression", "shards", "shard", "std_ddof")
# Options added after runs were recorded, with the value that reproduces the behaviour before
# them: at that value they are left out of the hashed configuration, which therefore reads as it
# did before the option existed (the code digest beside it changes with any change of the code
# anyway); any other value is hashed as usual.
_ADDED_OPTIONS: dict[tuple[str, ...], object] = {
    ("perception", "preview"): 0.0,
    ("sim",): "dynamic",
    ("state_lag",): False,
    ("plan", "metric"): "identity",
    ("plan", "final_velocity_space"): "joint",
    ("plan", "solver"): "levenberg",
    ("controller", "metric"): "identity",
    ("controller", "drift"): True,
    ("controller", "joint_only"): False,
    ("scenario", "plane_reference"): False,
    ("implementation",): "ours",
    ("scenario", "reference_offset"): [0.385, 1.147, -0.131],
    ("robot", "urdf"): "",
    ("robot", "joints"): [],
    ("robot", "tcp_frame"): "",
    ("robot", "package_dirs"): [],
    ("robot", "torque_limit"): [],
    ("robot", "velocity_limit"): [],
    ("controller", "disturbance"): "none",
    ("controller", "observer_bandwidth"): 20.0,
    ("controller", "observer_limit"): 1.0,
    ("controller", "integral_gain"): 10.0,
    ("controller", "integral_limit"): 50.0,
}


# ---------------------------------------------------------------------------- the code digest
@cache
def source_digest(root: Path = _AMEX_ROOT, leave_out: tuple[str, ...] = NOT_RESULT_CODE) -> str:
    """SHA-256 (16 hex digits) of the ``.py`` files under ``root``, paths and bytes, in order.

    ``leave_out``: path prefixes relative to ``root`` (directories end in ``/``). Computed once
    per process and arguments (module notes: "What the code hash promises").
    """
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        name = path.relative_to(root).as_posix()
        if "__pycache__" in name or name.startswith(leave_out):
            continue
        h.update(f"{name}\0{path.stat().st_size}\0".encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


@cache
def _numeric_versions() -> tuple[tuple[str, str], ...]:
    versions = []
    for name in NUMERIC_DISTRIBUTIONS:
        try:
            versions.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            versions.append((name, ""))
    return tuple(versions)


@cache
def _distributions() -> dict[str, list[str]]:
    return dict(metadata.packages_distributions())


@cache
def _module_digest(module_name: str) -> str:
    """A method module's bytes and its distribution's version; "" for a module of amex itself."""
    module = sys.modules.get(module_name) or importlib.import_module(module_name)
    file = getattr(module, "__file__", None)
    if file and Path(file).resolve().is_relative_to(_AMEX_ROOT):
        return ""  # in the source digest
    h = hashlib.sha256(module_name.encode())
    try:
        h.update(Path(file).read_bytes() if file else b"(no source file)")
    except OSError:
        h.update(b"(unreadable source file)")
    top = module_name.partition(".")[0]
    for dist in sorted(set(_distributions().get(top, [top]))):  # else: a dist named as the module
        # not from a distribution (a script's directory, PYTHONPATH): no version
        with contextlib.suppress(metadata.PackageNotFoundError):
            h.update(f"\0{dist}=={metadata.version(dist)}".encode())
    return h.hexdigest()[:16]


def method_class(name: str, implementation: str = "ours") -> type | None:
    """The class of method ``name``, or None if there is none (e.g. a plugin uninstalled).

    The registry is imported here, not with this module: reading a store (``analysis``,
    ``amex-log``) needs no method, and importing them all costs their kernels' libraries.
    """
    from amex.methods import get_method

    try:
        return get_method(name, implementation)
    except ConfigError:
        return None  # e.g. a plugin no longer installed


@cache
def _code_digest(method: type | None, shared_only: bool = False) -> str:
    spec = {
        "amex": source_digest(leave_out=NOT_RESULT_CODE + (METHOD_CODE,) * shared_only),
        "packages": _numeric_versions(),
    }
    if not shared_only:
        spec["method"] = "(unknown)" if method is None else _module_digest(method.__module__)
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:16]


def method_code_hash(name: str) -> str:
    """:func:`code_hash` of a run of method ``name`` with this code (``implementation=ours``)."""
    return _code_digest(method_class(name))


def code_hash(config: Any) -> str:
    """Digest of the code that computes ``config``'s episodes (module notes), 16 hex digits."""
    method = getattr(config, "method", None)
    name = getattr(method, "name", "")
    return _code_digest(method_class(name, getattr(config, "implementation", "ours")))


# ---------------------------------------------------------------------------- configuration hashes
def _without_neutral(spec: dict[str, Any]) -> dict[str, Any]:
    """``spec`` without the added options that have their neutral value (``_ADDED_OPTIONS``)."""
    spec = dict(spec)
    for path, neutral in _ADDED_OPTIONS.items():
        *sections, key = path
        node = spec
        for section in sections:
            sub = node.get(section)
            if not isinstance(sub, dict):
                break
            node[section] = node = dict(sub)
        else:
            if key in node and node[key] == neutral:
                del node[key]
    return spec


def _digest(spec: dict[str, Any], code: str) -> str:
    spec = {**_without_neutral(spec), "amex_version": __version__, "code": code}
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _spec(config: Any, leave_out: tuple[str, ...]) -> dict[str, Any]:
    """The hashed form of ``config`` (module notes), without the keys ``leave_out``."""
    spec = asdict(config)
    if hasattr(config, "method_config") and "method" not in leave_out:
        spec["method"] = asdict(config.method_config())
    robot = spec.get("robot")
    if isinstance(robot, dict) and not robot.get("q0"):
        from amex.robot import CATALOGUE

        known = CATALOGUE.get(robot.get("name", ""))
        if known is not None:
            robot["q0"] = list(known.q0)
    return {k: v for k, v in spec.items() if k not in (*_NOT_RESULTS, *leave_out)}


def config_hash(config: Any) -> str:
    """Hash of everything that determines an episode's result: configuration and code."""
    return _digest(_spec(config, ()), code_hash(config))


def scene_hash(config: Any) -> str:
    """Hash of the benchmark's shared settings and code: equal for all tasks and methods."""
    return _digest(_spec(config, ("task", "method")), _code_digest(None, shared_only=True))


@dataclass(frozen=True)
class RunIdentity:
    """What the rows of one run must carry; an empty field or None is not checked.

    Attributes:
        config_hash: :func:`config_hash` of the run.
        scene_hash: :func:`scene_hash` of the run.
        code_hash: :func:`code_hash` of the run.
        task: the task of every row.
        method: the method name of every row.
        seed: the scene seed of every row.
        episodes: the run's number of environments (``episodes`` of the rows it appends).
    """

    config_hash: str
    scene_hash: str = ""
    code_hash: str = ""
    task: int | None = None
    method: str = ""
    seed: int | None = None
    episodes: int | None = None

    @classmethod
    def of(cls, config: Any) -> RunIdentity:
        """The identity of a :class:`~amex.experiment.config.RunConfig`'s run."""
        return cls(
            config_hash(config),
            scene_hash(config),
            code_hash(config),
            int(config.task),
            str(config.method.name),
            int(config.seed),
            int(config.episodes),
        )
