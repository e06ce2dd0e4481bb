"""Motion-adaptation methods and their registry.

``METHODS`` maps each method's name (its module name and Hydra ``method=`` option) to its class.
"""

from __future__ import annotations

from amex.errors import ConfigError
from amex.methods.amex import AMEX, AMEXConfig
from amex.methods.base import Method, MethodConfig, Observation
from amex.methods.cr import CR, CRConfig
from amex.methods.dmp import DMP, DMPConfig
from amex.methods.dmp_ps import DMPPhaseStop, DMPPSConfig
from amex.methods.track import Track, TrackConfig

METHODS: dict[str, type[Method]] = {cls.name: cls for cls in (AMEX, CR, DMP, DMPPhaseStop, Track)}


def get_method(name: str) -> type[Method]:
    """The method class registered as ``name``; :class:`ConfigError` listing the valid names."""
    try:
        return METHODS[name]
    except KeyError:
        raise ConfigError.invalid("method", name, sorted(METHODS)) from None


__all__ = [
    "AMEX",
    "AMEXConfig",
    "CR",
    "CRConfig",
    "DMP",
    "METHODS",
    "DMPConfig",
    "DMPPSConfig",
    "DMPPhaseStop",
    "Method",
    "MethodConfig",
    "Observation",
    "Track",
    "TrackConfig",
    "get_method",
]
