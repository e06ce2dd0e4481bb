"""The ``/method`` topic of a log: a method's ``internals()`` at every outer step, as JSON.

The channel and its schema are made at the first step from the values then
(:func:`amex.log.messages.object_schema`); later a key the schema lacks is left out, and a value
of another kind is written as null. Numbers keep their full precision (``float.__repr__``, as
``json`` writes them), non-finite numbers become null, number arrays of more than 64 entries or
of another shape than (k,) are left out.

:meth:`MethodTopic.encode` formats a step through a recipe made once per combination of keys and
value types (floats, ints, flags, texts, None, 1-D number arrays): ~4x less Python per step than
building and encoding a dict. :meth:`MethodTopic.reference_encode` is that dict path, the oracle
(tests/log/test_method_topic.py compares them), and what any other value or a non-finite number
takes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from json.encoder import encode_basestring_ascii
from typing import Any

import numpy as np

from amex.log import messages as M

MAX_ARRAY = 64  # entries of the largest array that is logged per step

#: The schema kind of the common value types of ``internals()`` (what M.value_schema gives).
_KINDS: dict[type, str] = {
    bool: "boolean",
    int: "number",
    float: "number",
    np.float64: "number",
    np.int64: "number",
    str: "string",
}


class _Slow(Exception):
    """A value the recipe does not cover (e.g. a non-finite number): take the dict path."""


Converter = Callable[[Any], "str | None"]  # a value's JSON text, None: leave the key out


def _kind_of(value: Any) -> str | None:
    """The schema kind (``number``, ``array``, ...) of one value, None if it has none."""
    schema = M.value_schema(value)
    return None if schema is None else schema["type"]


class MethodTopic:
    """The schema and the messages of ``/method`` (module notes)."""

    def __init__(self) -> None:
        self.kinds: dict[str, str] | None = None
        self._recipes: dict[tuple[Any, ...], tuple[tuple[str, Converter], ...] | None] = {}

    def schema(self, t: float, internals: dict[str, Any]) -> dict[str, Any]:
        """The channel's JSON schema, from the first step's values (sets :attr:`kinds`)."""
        method: dict[str, Any] = {"t": t}
        for key, value in internals.items():
            if isinstance(value, np.ndarray):
                if value.size > MAX_ARRAY or value.ndim != 1:
                    continue  # large arrays do not belong in a per-step JSON message
                value = value.tolist()
            method[key] = value
        schema = M.object_schema("amex.MethodInternals", method)
        self.kinds = {k: v["type"] for k, v in schema["properties"].items()}
        return schema

    def encode(self, t: float, internals: dict[str, Any]) -> bytes:
        """The message of one step (after :meth:`schema`); equal to :meth:`reference_encode`."""
        signature = (tuple(internals), tuple(map(type, internals.values())))
        try:
            recipe = self._recipes[signature]
        except KeyError:
            recipe = self._recipes[signature] = self._recipe(*signature)
        if recipe is None or not math.isfinite(t):
            return self.reference_encode(t, internals)
        parts = ['"t":' + float.__repr__(t)] if "t" in self.kinds else []  # type: ignore[operator]
        try:
            for (prefix, convert), value in zip(recipe, internals.values(), strict=True):
                text = convert(value)
                if text is not None:
                    parts.append(prefix + text)
        except _Slow:
            return self.reference_encode(t, internals)
        return ("{" + ",".join(parts) + "}").encode()

    def reference_encode(self, t: float, internals: dict[str, Any]) -> bytes:
        """The message of one step, built as a dict and JSON-encoded (the oracle)."""
        kinds = self.kinds
        if kinds is None:
            raise ValueError("MethodTopic.schema must be called first")
        message: dict[str, Any] = {"t": t} if "t" in kinds else {}
        for key, value in internals.items():
            kind = kinds.get(key)
            if kind is None or key == "t":
                continue
            if isinstance(value, np.ndarray):
                if value.size > MAX_ARRAY or value.ndim != 1:
                    continue  # as at the first step
                numbers = value.dtype.kind in "fiu"  # tolist() gives Python ints and floats
                value = value.tolist()
                fits = kind == "array" if numbers else _kind_of(value) == kind
            else:
                known = _KINDS.get(type(value))
                fits = known == kind if known is not None else _kind_of(value) == kind
            message[key] = value if fits else None
        return M.dumps(message)

    def _recipe(
        self, keys: tuple[str, ...], types: tuple[type, ...]
    ) -> tuple[tuple[str, Converter], ...] | None:
        """Per key, its JSON prefix and the converter of its value; None: no fast path."""
        kinds = self.kinds or {}
        recipe: list[tuple[str, Converter]] = []
        for key, kind_type in zip(keys, types, strict=True):
            kind = kinds.get(key)
            if kind is None or key == "t":
                recipe.append(("", _omit))
                continue
            convert = _converter(kind_type, kind)
            if convert is None:
                return None
            recipe.append((encode_basestring_ascii(key) + ":", convert))
        return tuple(recipe)


def _omit(value: Any) -> None:
    return None


def _null(value: Any) -> str:
    return "null"


def _number(value: float) -> str:
    if not math.isfinite(value):
        raise _Slow
    return float.__repr__(value)


def _integer(value: int) -> str:
    return int.__repr__(int(value))


def _flag(value: bool) -> str:
    return "true" if value else "false"


def _float_array(value: np.ndarray) -> str | None:
    if value.size > MAX_ARRAY or value.ndim != 1:
        return None
    if value.dtype.kind != "f":
        raise _Slow
    text = ",".join(map(float.__repr__, value.tolist()))
    if "n" in text:  # nan or inf: not JSON
        raise _Slow
    return "[" + text + "]"


def _array_null(value: np.ndarray) -> str | None:
    if value.size > MAX_ARRAY or value.ndim != 1:
        return None
    if value.dtype.kind not in "fiu":
        raise _Slow
    return "null"


def _converter(value_type: type, kind: str) -> Converter | None:
    """The converter of values of ``value_type`` under a schema ``kind``; None if not covered."""
    if value_type is type(None):
        return _null
    if value_type is np.ndarray:
        return _float_array if kind == "array" else _array_null
    known = _KINDS.get(value_type)
    if known is None:
        return None
    if known != kind:
        return _null
    if value_type in (float, np.float64):
        return _number
    if value_type in (int, np.int64):
        return _integer
    if value_type is bool:
        return _flag
    return encode_basestring_ascii  # str
