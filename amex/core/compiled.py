"""The kernels a run calls, compiled ahead of time: a run of most methods without Numba loaded.

amex's compiled kernels are Numba functions (``numba.njit(cache=True)``). Calling one, even from
Numba's warm on-disk cache, needs Numba imported and its CPU target initialised: ~0.26 s of CPU in
every process (``make bench``, start-up), a third of a short run's start-up and paid again by
every SLURM array task and joblib worker. The few kernels a run of the episode loop calls are
therefore also built ahead of time, from the same source, into one C extension
(:mod:`amex.app.build_kernels`, run by ``make install``): :data:`EXPORTS`, the episode step
(:mod:`amex.sim.step_kernel`), AMEX's update (Eq. 7-9, :mod:`amex.methods.amex_kernels`), the
clearance terms of the CBF methods and RMPflow's resolve. A run that calls nothing else (AMEX,
the DMPs, tracking, the CBF methods, RMPflow, without ``log=full``, its plan cached) never
imports Numba; CR's Gauss-Newton loop, MPPI's rollouts, the planner, the disturbance observer
and the log's encoders still load their kernels through Numba, on first use.

A caller must pass exactly the types of :attr:`Export.args`: the library's wrappers convert
their arguments without checking them (an array of another dtype or layout is read as if it were
the declared one), where Numba's dispatcher would compile another version.
``tests/core/test_compiled.py`` checks that the runs of every exported kernel compile one
signature each under Numba, the exported one.

:func:`kernel` hands out a kernel: the ahead-of-time function where the library was built from
exactly these sources, else the Numba dispatcher (importing its module). The library's name
carries a :func:`fingerprint` of every source file the kernels compile (:data:`SOURCES`), the
export list, the Python version and Numba's version: a library built from other sources is
never loaded, so an edited kernel runs as Numba compiles it until the library is built again.
``AMEX_AOT=0`` turns the library off (Numba for every kernel); ``AMEX_AOT_DIR`` moves it from the
package's ``__pycache__``.

The same numbers: both are the same Numba compilation of the same Python source without
``fastmath`` (IEEE operations in program order). The library is built for the generic x86-64 CPU
(no host-specific instructions, so one build serves every machine of a cluster), Numba's JIT for
the host's; LLVM contracts nothing into FMAs and reassociates nothing without ``fastmath``, so the
results are the same bits (tested on episodes of every exported method, ``make paper`` rows
compared).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Callable
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any, NamedTuple

__all__ = [
    "EXPORTS",
    "SOURCES",
    "Export",
    "digest",
    "fingerprint",
    "kernel",
    "library",
    "library_dir",
    "library_path",
    "module_name",
    "symbol",
]

_PACKAGE = Path(__file__).resolve().parents[1]  # the amex package


class Export(NamedTuple):
    """One kernel in the ahead-of-time library, with the argument types runs call it with.

    ``args`` spells the types one per word: ``f`` and ``i`` a float64 and an int64 scalar, ``b``
    a bool, ``fN`` and ``iN`` a C-contiguous float64 and int64 array of N dimensions.
    """

    module: str
    name: str
    args: str


#: The kernels of the episode loop and of the methods built on it (module notes).
EXPORTS: tuple[Export, ...] = (
    Export("amex.sim.step_kernel", "episode_step", "i1 f2 f1 i i"),
    Export("amex.sim.step_kernel", "clip_torque", "i1 f1"),
    Export("amex.sim.step_kernel", "speeds_within_limit", "i1"),
    Export("amex.methods.amex_kernels", "amex_update", "f1 f1 f1 f1 f1 f2 f2 f1 f1"),
    Export(
        "amex.methods.clearance_kernels",
        "pair_terms",
        "i1 f3 f2 f3 f2 f2 f2 f2 f2 f2 f2 f2 f1 b f2 f1 f1",
    ),
    Export(
        "amex.methods.rmpflow_kernels",
        "resolve",
        "f2 f1 f1 f1 f1 f1 f1 f1 f1 f1 f2 f1 f1 f1 f1 f1 f1 f1 f1 f2 f1 f1",
    ),
)

#: Every amex source file the exported kernels compile, relative to the package: their modules
#: and what those import from amex (tests/core/test_compiled.py checks the list is whole).
SOURCES: tuple[str, ...] = (
    "core/errors.py",
    "core/types.py",
    "control/collision_kernels.py",
    "control/kernels.py",
    "control/packing.py",
    "methods/amex_kernels.py",
    "methods/amex_layout.py",
    "methods/clearance_kernels.py",
    "methods/rmpflow_kernels.py",
    "sim/step_kernel.py",
    "sim/step_layout.py",
)

_EXPORTED = frozenset((e.module, e.name) for e in EXPORTS)


def symbol(module: str, name: str) -> str:
    """Kernel ``module.name``'s name in the library (``amex_sim_step_kernel__episode_step``)."""
    return f"{module.replace('.', '_')}__{name}"


def _numba_version() -> str:
    try:
        from importlib.metadata import version

        return version("numba")
    except Exception:  # no distribution metadata: never matches a built library
        return "unknown"


def digest(package: Path) -> str:
    """The fingerprint of the sources under ``package`` (an amex tree), 16 hex digits."""
    h = hashlib.sha256()
    h.update(f"{sys.implementation.cache_tag} numba {_numba_version()}\n".encode())
    h.update(repr(EXPORTS).encode())
    for name in SOURCES:
        h.update(name.encode())
        h.update((package / name).read_bytes())
    return h.hexdigest()[:16]


@cache
def fingerprint() -> str:
    """The digest naming the library built from this package's sources (module notes)."""
    return digest(_PACKAGE)


def library_dir() -> Path:
    """Where the library lives: ``AMEX_AOT_DIR``, else the package's ``__pycache__``."""
    return Path(os.environ.get("AMEX_AOT_DIR") or _PACKAGE / "__pycache__")


def module_name() -> str:
    """The library's module name (its ``PyInit_`` symbol): ``amex_aot_<fingerprint>``."""
    return f"amex_aot_{fingerprint()}"


def library_path() -> Path:
    """The file of the library built from today's sources."""
    return library_dir() / (module_name() + importlib.machinery.EXTENSION_SUFFIXES[0])


@cache
def library() -> ModuleType | None:
    """The ahead-of-time library of today's sources, or None (not built, or ``AMEX_AOT=0``)."""
    if os.environ.get("AMEX_AOT", "1") == "0":
        return None
    path = library_path()
    if not path.is_file():
        return None
    loader = importlib.machinery.ExtensionFileLoader(module_name(), str(path))
    spec = importlib.util.spec_from_file_location(module_name(), path, loader=loader)
    if spec is None:
        return None
    try:
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
    except ImportError:  # a broken or foreign build: Numba compiles instead
        return None
    sys.modules[module.__name__] = module  # its functions pickle and copy by name
    return module


def kernel(module: str, name: str) -> Callable[..., Any]:
    """Kernel ``name`` of ``module``: ahead of time where built (module notes), else Numba's."""
    if (module, name) in _EXPORTED:
        lib = library()
        if lib is not None:
            return getattr(lib, symbol(module, name))  # type: ignore[no-any-return]
    return getattr(importlib.import_module(module), name)  # type: ignore[no-any-return]
