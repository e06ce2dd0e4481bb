"""Lengths stated in the original experiment's units, converted to a robot's scene in one place.

The original scenes were made for a 2.6 m arm; a smaller arm runs them scaled by
``scenario.scale`` (the Panda and the UR5: 0.2; the original chain: 1). Every configuration field
whose value depends on the scene's size is stated at its original value and marked with the power
of the scale it carries (``field(metadata=scaled(1))`` for a length, ``scaled(2)`` for a weight
that balances a dimensionless error against squared lengths, ``scaled(-2)`` for a gain per
squared length); :func:`to_scene_units` returns a copy with every marked field converted,
recursing into nested configurations. Nothing else in amex multiplies by the scale.

The conversion multiplies (or divides) by ``scale`` once per power, in that order, so that its
rounding is the same wherever it happens: ``0.1 * 0.2`` is 0.020000000000000004 m, the same for
the inner controller's collision margin and for CR's.
"""

from __future__ import annotations

import dataclasses
from typing import Any, TypeVar

SCALE_KEY = "scale_power"

T = TypeVar("T")


def scaled(power: int) -> dict[str, int]:
    """Field metadata: the value is in original units and carries ``scale ** power``."""
    return {SCALE_KEY: power}


def scale_value(value: float, scale: float, power: int) -> float:
    """``value * scale ** power``, one multiplication (or division) per power."""
    out = float(value)
    for _ in range(abs(power)):
        out = out * scale if power > 0 else out / scale
    return out


def scale_power(cls: type, name: str) -> int:
    """The power of the scale the field ``name`` of dataclass ``cls`` carries (0: none)."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            return int(f.metadata.get(SCALE_KEY, 0))
    raise KeyError(name)


def to_scene_units(config: T, scale: float) -> T:
    """A copy of the dataclass ``config`` with every marked field in the scene's units.

    Lists are converted element by element; nested dataclasses recursively.
    """
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(config):  # type: ignore[arg-type]
        value = getattr(config, f.name)
        power = int(f.metadata.get(SCALE_KEY, 0))
        if power:
            if isinstance(value, (list, tuple)):
                changes[f.name] = type(value)(scale_value(v, scale, power) for v in value)
            else:
                changes[f.name] = scale_value(value, scale, power)
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            changes[f.name] = to_scene_units(value, scale)
    return dataclasses.replace(config, **changes)  # type: ignore[type-var]
