"""Motion-adaptation methods and their registry.

``METHODS`` maps each method's name (its module name and Hydra ``method=`` option) to its class.

Every method is built the same way, ``Cls(plan, config, dt, robot)`` (:class:`Method`).

Methods from other packages join the registry through the entry-point group ``amex.methods``
(``name = "package.module:Class"`` in the package's ``pyproject.toml``): the class must subclass
:class:`Method`, with ``name`` and its config class's default ``name`` equal to the entry point's
name, and take the constructor arguments above, passing them to ``super().__init__`` (which
checks them; the config's own ``validate()`` holds the method's range checks). Such a method is
then ``method=<name>`` on the command line, with its config dataclass's defaults (override fields
as ``method.<field>=...``), in sweeps, tables and ``make bench``. A plugin that fails to load, or
whose name is taken, is skipped with a warning saying why, so it cannot stop the built-in methods
from running.
"""

from __future__ import annotations

import warnings
from importlib.metadata import entry_points

from amex.core.errors import ConfigError
from amex.methods.amex import AMEX, AMEXConfig
from amex.methods.amex_cbf import AMEXCBF, AMEXCBFConfig
from amex.methods.base import Method, MethodConfig, Observation
from amex.methods.cbf_ik import CBFIK, CBFIKConfig
from amex.methods.cr import CR, CRConfig
from amex.methods.dmp import DMP, DMPConfig
from amex.methods.dmp_avoid import DMPAvoid, DMPAvoidConfig
from amex.methods.dmp_ps import DMPPhaseStop, DMPPSConfig
from amex.methods.mppi import MPPI, MPPIConfig
from amex.methods.original.amex import AMEXOriginal
from amex.methods.original.cr import CROriginal
from amex.methods.original.dmp import DMPOriginal
from amex.methods.rmpflow import RMPflow, RMPflowConfig
from amex.methods.track import Track, TrackConfig
from amex.plan.reference import ReferencePlan

METHODS: dict[str, type[Method]] = {
    cls.name: cls
    for cls in (AMEX, CR, DMP, DMPPhaseStop, Track, RMPflow, CBFIK, AMEXCBF, DMPAvoid, MPPI)
}
BUILTIN_METHODS = frozenset(METHODS)
IMPLEMENTATIONS = ("ours", "original")
#: The authors' implementations of the paper's methods (``implementation=original``), by name.
ORIGINAL_METHODS: dict[str, type[Method]] = {
    cls.name: cls for cls in (AMEXOriginal, CROriginal, DMPOriginal)
}
ENTRY_POINT_GROUP = "amex.methods"


def _plugin_problem(name: str, cls: object) -> str:
    """Why ``cls`` cannot be registered as ``name`` ("" if it can)."""
    if name in METHODS:
        return f"the name is taken by {METHODS[name].__module__}.{METHODS[name].__qualname__}"
    if not (isinstance(cls, type) and issubclass(cls, Method)):
        return f"{cls!r} is not a subclass of amex.methods.Method"
    if cls.name != name:
        return f"its class's name is {cls.name!r}"
    if not issubclass(cls.config_class, MethodConfig):
        return f"its config_class {cls.config_class!r} is not a MethodConfig"
    if cls.config_class().name != name:
        return f"its config_class's default name is {cls.config_class().name!r}"
    return ""


def load_plugins() -> list[str]:
    """Register the methods of the ``amex.methods`` entry points; the names added.

    Called once at import. A plugin that cannot be imported or does not fit (see the module
    notes) is skipped with a :class:`RuntimeWarning` naming the entry point and the reason.
    """
    added = []
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        try:
            cls = ep.load()
        except Exception as e:  # a broken third-party package must not stop the built-ins
            problem = f"it failed to import: {type(e).__name__}: {e}"
        else:
            problem = _plugin_problem(ep.name, cls)
        if problem:
            warnings.warn(
                f"amex: method plugin {ep.name} = {ep.value} skipped: {problem}",
                RuntimeWarning,
                stacklevel=2,
            )
            continue
        METHODS[ep.name] = cls
        added.append(ep.name)
    return added


load_plugins()


def get_method(name: str, implementation: str = "ours") -> type[Method]:
    """The method class registered as ``name``; :class:`ConfigError` listing the valid names.

    With ``implementation="original"``, the authors' implementation of amex, dmp or cr
    (:data:`ORIGINAL_METHODS`); other methods have only theirs.
    """
    if implementation not in IMPLEMENTATIONS:
        raise ConfigError.invalid("implementation", implementation, IMPLEMENTATIONS)
    if implementation == "original" and name in ORIGINAL_METHODS:
        return ORIGINAL_METHODS[name]
    try:
        return METHODS[name]
    except KeyError:
        raise ConfigError.invalid("method", name, sorted(METHODS)) from None


__all__ = [
    "AMEX",
    "AMEXOriginal",
    "CROriginal",
    "DMPOriginal",
    "IMPLEMENTATIONS",
    "ORIGINAL_METHODS",
    "BUILTIN_METHODS",
    "ENTRY_POINT_GROUP",
    "AMEXCBF",
    "AMEXCBFConfig",
    "AMEXConfig",
    "CBFIK",
    "CBFIKConfig",
    "CR",
    "CRConfig",
    "DMP",
    "METHODS",
    "DMPAvoid",
    "DMPAvoidConfig",
    "MPPI",
    "MPPIConfig",
    "DMPConfig",
    "DMPPSConfig",
    "DMPPhaseStop",
    "Method",
    "MethodConfig",
    "Observation",
    "RMPflow",
    "RMPflowConfig",
    "ReferencePlan",
    "Track",
    "TrackConfig",
    "get_method",
    "load_plugins",
]
