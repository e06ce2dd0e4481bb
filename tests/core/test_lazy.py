"""LazyDict reads as a dict, whichever way it is read, and computes a Lazy value once."""

from __future__ import annotations

import copy
import json
import pickle

import pytest

from amex.core.lazy import Lazy, LazyDict


def make(calls: list[int]) -> LazyDict:
    return LazyDict(a=1, plan=Lazy(lambda: calls.append(1) or [1.0, 2.0]))


READS = {
    "getitem": lambda d: {"plan": d["plan"]},
    "get": lambda d: {"plan": d.get("plan")},
    "items": lambda d: dict(d.items()),
    "values": lambda d: dict(zip(d.keys(), d.values(), strict=True)),
    "dict": dict,
    "unpack": lambda d: {**d},
    "or": lambda d: {} | d,
    "copy": lambda d: d.copy(),
    "copy.copy": copy.copy,
    "deepcopy": copy.deepcopy,
    "pickle": lambda d: pickle.loads(pickle.dumps(d)),
    "json": lambda d: json.loads(json.dumps(d)),
    "pop": lambda d: {"plan": d.pop("plan")},
    "popitem": lambda d: dict([d.popitem()]),
    "setdefault": lambda d: {"plan": d.setdefault("plan", None)},
}


@pytest.mark.parametrize("read", READS)
def test_every_read_gives_the_computed_value(read):
    calls: list[int] = []
    d = make(calls)
    assert list(d) == ["a", "plan"] and "plan" in d and len(d) == 2 and not calls
    out = READS[read](d)
    assert out["plan"] == [1.0, 2.0] and calls == [1]


def test_computed_once_and_compares_as_a_dict():
    calls: list[int] = []
    d = make(calls)
    plain = {"a": 1, "plan": [1.0, 2.0]}
    assert d == plain and plain == d  # noqa: SIM300 (the reflected comparison)
    assert d["plan"] is d["plan"] and calls == [1]
    assert repr(d) == repr({"a": 1, "plan": [1.0, 2.0]})


@pytest.mark.parametrize("read", [read for read in READS if read != "json"])  # (arrays)
def test_a_rowwise_value_is_computed_by_every_read_and_its_rows_alone(read):
    import numpy as np

    from amex.core.lazy import LazyRows

    calls: list[int] = []
    knots = np.arange(12.0).reshape(4, 3)

    def double(rows):
        calls.append(len(rows))
        return rows * 2.0

    lazy = LazyRows.rowwise(double, knots, group=("double",))
    assert isinstance(lazy, LazyRows) and isinstance(lazy, Lazy)
    assert (lazy.length, lazy.source, lazy.map, lazy.group) == (4, knots, double, ("double",))
    np.testing.assert_array_equal(lazy.take(np.array([3, 1])), knots[[3, 1]] * 2.0)
    assert calls == [2]
    d = LazyDict(a=1, plan=lazy)
    out = READS[read](d)
    assert np.array_equal(out["plan"], knots * 2.0) and calls == [2, 4]
