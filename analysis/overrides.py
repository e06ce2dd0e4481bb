"""Command-line overrides as a sweep states them (``key=a,b,c``), parsed without Hydra.

Enough of Hydra's override grammar for the sweeps of ``conf/study/``: ``key=value``,
``+key=value``, ``~key``, comma lists as sweeps (commas inside brackets or quotes belong to the
value) and the product of a sweep's overrides as Hydra's basic sweeper forms it (a key keeps its
first position and takes its last value). Values are compared as YAML reads them, so ``False``,
``false`` and ``'false'`` are one value, as are ``0`` and ``0.0``.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import yaml

from amex.core.errors import AmexError

#: Hydra's sweep functions, which the reports do not expand (they read comma lists only).
FUNCTIONS = ("range(", "choice(", "interval(", "glob(", "tag(", "sort(", "shuffle(")


class OverrideError(AmexError):
    """An override the reports cannot read; the message quotes it."""


def value_of(text: str) -> Any:
    """The value that ``text`` stands for (YAML's reading; ``null`` and ``''`` stay text)."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return text if value is None else value


def split_top_level(text: str) -> list[str]:
    """``text`` split at the commas outside brackets and quotes."""
    parts: list[str] = []
    current: list[str] = []
    depth, quote = 0, ""
    for char in text:
        if quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char in "[{(":
            depth += 1
        elif char in "]})":
            depth -= 1
        elif char == "," and depth == 0:
            parts.append("".join(current))
            current = []
            continue
        current.append(char)
    parts.append("".join(current))
    return parts


def parse(override: str) -> tuple[str, list[str]]:
    """``(key, value texts)`` of one override: several texts for a sweep, one otherwise.

    Raises:
        OverrideError: a sweep function (``range(...)``, ``choice(...)``, ...).
    """
    key, sep, text = override.partition("=")
    key = key.strip().removeprefix("++").removeprefix("+")
    if not sep:
        return key, [""]  # ~key: a deletion
    text = text.strip()
    if text.startswith(FUNCTIONS):
        raise OverrideError(f"{override!r}: the reports read comma lists only, not {text}")
    return key, [part.strip() for part in split_top_level(text)]


def job_of(overrides: Iterable[str]) -> dict[str, str]:
    """One job's overrides (as ``.hydra/overrides.yaml`` lists them) as ``{key: value text}``."""
    job = {}
    for override in overrides:
        key, _, text = override.partition("=")
        job[key.strip().removeprefix("++").removeprefix("+")] = text.strip()
    return job


def as_text(value: Any) -> str:
    """A config value as an override writes it (booleans as ``true``/``false``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def product(overrides: Iterable[str]) -> list[dict[str, str]]:
    """Every job of ``overrides`` (sweeps expanded) as ``{key: value text}``, in Hydra's order."""
    values: dict[str, list[str]] = {}
    for override in overrides:
        key, texts = parse(override)
        values[key] = texts  # a repeated key keeps its place and takes the later values
    return [dict(zip(values, combo, strict=True)) for combo in itertools.product(*values.values())]


def from_mapping(mapping: Mapping[str, Any] | None) -> list[str]:
    """``{key: value}`` of a sweeper's ``params`` or of one grid as override texts."""
    return [f"{key}={as_text(value)}" for key, value in (mapping or {}).items()]


def normalized(job: Mapping[str, str], leave_out: Sequence[str] = ()) -> dict[str, Any]:
    """``job`` with its values as YAML reads them, the keys ``leave_out`` left out."""
    return {k: value_of(v) for k, v in job.items() if k not in leave_out}
