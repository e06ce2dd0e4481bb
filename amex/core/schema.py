"""One validation pass over a configuration, generated from its dataclass schema.

:func:`check_tree` walks a configuration's dataclasses (nested dataclasses, lists, dicts) and
applies rules that follow from the declarations alone, so a field or a config group added later is
covered without being listed anywhere:

* every number (int or float, alone or in a list) must be finite: no ``nan``, no ``inf``;
* a scalar number must be >= 0, unless its field declares other limits (``metadata=limits(gt=0)``,
  ``metadata=SIGNED``) or its default is negative (a sentinel such as ``-1``); numbers in lists
  (coordinates, joint angles) are only required to be finite unless their field declares limits;
* an attribute that is not a field of its dataclass is an unknown key (``+scenario.scal=0.5``);
* a nested dataclass with a ``validate()`` method runs it once its own fields passed, for the rules
  that relate several fields.

The first violation raises :class:`~amex.core.errors.ConfigError` naming the dotted key, the value
and
what is valid.
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, fields, is_dataclass
from numbers import Real
from typing import Any

from amex.core.errors import ConfigError


@dataclass(frozen=True)
class Limits:
    """Bounds of a numeric field (None: unbounded on that side)."""

    ge: float | None = 0.0
    gt: float | None = None
    le: float | None = None
    lt: float | None = None

    def admits(self, x: float) -> bool:
        """Whether ``x`` lies within the bounds."""
        return not (
            (self.ge is not None and not x >= self.ge)
            or (self.gt is not None and not x > self.gt)
            or (self.le is not None and not x <= self.le)
            or (self.lt is not None and not x < self.lt)
        )

    def describe(self, integer: bool) -> str:
        """In words, e.g. ``a finite number >= 0``."""
        kind = "an integer" if integer else "a finite number"
        parts = [
            f"{op} {_number(bound)}"
            for op, bound in ((">=", self.ge), (">", self.gt), ("<=", self.le), ("<", self.lt))
            if bound is not None
        ]
        return f"{kind} {' and '.join(parts)}" if parts else kind


def _number(x: float) -> str:
    """A bound in words: whole numbers without an exponent (1000000), others as ``%g``."""
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


NON_NEGATIVE = Limits()
FINITE = Limits(ge=None)
#: ``field(..., metadata=SIGNED)``: a scalar that may be negative (only finiteness is checked).
SIGNED = {"limits": FINITE}


def limits(
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
) -> dict[str, Limits]:
    """Field metadata declaring a numeric field's bounds: ``field(default=1e-6, metadata=...)``."""
    return {"limits": Limits(ge=ge, gt=gt, le=le, lt=lt)}


def _is_number(value: Any) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool)


def _default(f: Any) -> Any:
    if f.default is not MISSING:
        return f.default
    return None


def _field_limits(f: Any, scalar: bool) -> Limits:
    declared = f.metadata.get("limits") if f.metadata else None
    if declared is not None:
        return declared
    if not scalar:
        return FINITE
    default = _default(f)
    if _is_number(default) and default < 0:  # a negative default: the field is signed
        return FINITE
    return NON_NEGATIVE


def _check_number(key: str, value: Any, rule: Limits) -> None:
    integer = isinstance(value, int)
    x = float(value)
    if not math.isfinite(x) or not rule.admits(x):
        raise ConfigError.invalid(key, value, rule.describe(integer))


def _check_value(key: str, value: Any, rule: Limits) -> None:
    if _is_number(value):
        _check_number(key, value, rule)
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            _check_value(f"{key}[{i}]", item, rule)
    elif isinstance(value, dict):
        for k, item in value.items():
            _check_value(f"{key}.{k}", item, rule)
    elif is_dataclass(value) and not isinstance(value, type):
        _check_node(value, f"{key}.")


def field_names(node: Any) -> list[str]:
    """The field names of a dataclass instance or class."""
    return [f.name for f in fields(node)]


def _check_node(node: Any, prefix: str) -> None:
    names = field_names(node)
    extra = sorted(k for k in vars(node) if k not in names and not k.startswith("_"))
    if extra:
        where = f" of {prefix[:-1]}" if prefix else ""
        raise ConfigError(
            f"unknown config key {prefix + extra[0]!r}; valid keys{where}: {', '.join(names)}"
        )
    for f in fields(node):
        value = getattr(node, f.name)
        _check_value(prefix + f.name, value, _field_limits(f, _is_number(value)))
    if prefix:  # a nested node's own rules (the root's caller runs the root's)
        validate = getattr(node, "validate", None)
        if callable(validate):
            validate()


def check_tree(config: Any, prefix: str = "") -> None:
    """Check every field of the dataclass ``config`` and of its nested nodes (module notes).

    Args:
        config: a dataclass instance (e.g. :class:`~amex.experiment.config.RunConfig`).
        prefix: dotted key of ``config`` within a larger configuration (``"method."``), for
            messages.

    Raises:
        ConfigError: the first non-finite or out-of-range number, or unknown key.
    """
    _check_node(config, prefix)
