"""A dict whose values may be computed at their first read: a method's costly ``internals()``.

:class:`LazyDict` is an ordinary ``dict`` to its readers (``d[k]``, ``get``, ``items``,
``values``, ``pop``, ``copy``, ``dict(d)``, ``{**d}``, ``==``, pickling, JSON): a value given
as a :class:`Lazy` is computed when it is first read, through any of them, and then kept. Its
keys, ``in`` and ``len`` never compute anything. CR's planned TCP path (~0.1 ms of kinematics)
is one: an outer step that nobody logs, or whose plan the logger skips, does not pay for it.

The thunk must capture what it needs at creation (a snapshot: CR's knots are a new array at
every solve, never written in place), so a late read gives the value of the step it belongs to.

A :class:`LazyRows` is a lazy array whose rows can also be computed alone: a reader that needs
only some of them takes the raw value (``dict.get(d, key)``, which resolves nothing) and calls
:meth:`LazyRows.take`. The log's scene draws at most 100 points of a plan of up to ~400 knots
(:mod:`amex.log.scene`), and it does so in its batch, after the steps, where the kinematics run
warm; every other reader gets the whole array, as before.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

__all__ = ["Lazy", "LazyDict", "LazyRows"]


class Lazy:
    """A value computed by ``compute()`` when a :class:`LazyDict` first hands it out."""

    __slots__ = ("compute",)

    def __init__(self, compute: Callable[[], Any]) -> None:
        self.compute = compute


class LazyRows(Lazy):
    """A lazy ``(length, ...)`` array: ``rows(None)`` gives it whole, ``rows(index)`` some rows.

    Args:
        length: the number of rows of the whole array.
        rows: computes the rows of an integer index array (in its order), or all for None;
            ``rows(index)`` must equal ``rows(None)[index]``, bit for bit.

    Attributes:
        source, map, group: for :meth:`rowwise`'s, its rows, the map of rows and its group;
            else None.
    """

    __slots__ = ("length", "rows", "source", "map", "group")

    def __init__(self, length: int, rows: Callable[[Any], Any]) -> None:
        super().__init__(lambda: rows(None))
        self.length = length
        self.rows = rows
        self.source: Any = None
        self.map: Callable[[Any], Any] | None = None
        self.group: Any = None

    @classmethod
    def rowwise(cls, compute: Callable[[Any], Any], rows: Any, group: Any = None) -> LazyRows:
        """``compute(rows)``, lazily, for a ``compute`` that maps each row on its own.

        A plan's knots to their TCP positions: some rows are ``compute(rows[index])``.

        Args:
            compute: the map of rows (``compute(a)[i]`` depends on ``a[i]`` alone, bit for bit).
            rows: its input, shape (length, ...).
            group: a hashable key shared by lazies whose ``compute`` is the same map: a reader
                may then compute rows of several of them in one call, on their rows stacked
                (the log's scene, a batch's drawn plans at a time). None: no group.
        """
        lazy = object.__new__(_Rowwise)  # no closures: made at every step of CR and MPPI
        lazy.length, lazy.source, lazy.map, lazy.group = len(rows), rows, compute, group
        return lazy

    def take(self, index: Any) -> Any:
        """The rows ``index`` (an integer array; None: all), computed now (class notes)."""
        return self.rows(index)


class _Rowwise(LazyRows):
    """:meth:`LazyRows.rowwise`'s: ``compute`` and ``rows`` map the rows of its ``source``."""

    __slots__ = ()

    def compute(self) -> Any:  # type: ignore[override]
        """All the rows, ``map(source)`` (the base's slot of a callable, as a method)."""
        return self.map(self.source)  # type: ignore[misc]

    def rows(self, index: Any) -> Any:  # type: ignore[override]
        """The rows ``index`` (None: all), ``map(source[index])``."""
        return self.map(self.source if index is None else self.source[index])  # type: ignore[misc]


_LAZY = (Lazy, LazyRows, _Rowwise)


class LazyDict(dict):  # type: ignore[type-arg]
    """A ``dict`` computing its :class:`Lazy` values at their first read (module notes)."""

    def _resolve(self, key: Any, value: Any) -> Any:
        if type(value) in _LAZY:
            value = value.compute()
            dict.__setitem__(self, key, value)
        return value

    def _resolved(self) -> None:
        for key, value in list(dict.items(self)):
            if type(value) in _LAZY:
                self._resolve(key, value)

    def __getitem__(self, key: Any) -> Any:
        return self._resolve(key, dict.__getitem__(self, key))

    def get(self, key: Any, default: Any = None) -> Any:
        """``d[key]``, or ``default`` without the key."""
        return self[key] if key in self else default  # noqa: SIM401 (self.get is this)

    def pop(self, key: Any, *default: Any) -> Any:
        """Remove ``key``; its value (computed), or ``default``."""
        if key in self:
            value = self[key]
            dict.__delitem__(self, key)
            return value
        return dict.pop(self, key, *default)

    def popitem(self) -> tuple[Any, Any]:
        """Remove and return the last (key, value), computed."""
        self._resolved()
        return dict.popitem(self)

    def setdefault(self, key: Any, default: Any = None) -> Any:
        """``d[key]`` (computed), or ``default`` stored under ``key``."""
        return self[key] if key in self else dict.setdefault(self, key, default)

    def __iter__(self) -> Iterator[Any]:  # defined so that dict(d) and {**d} read through []
        return dict.__iter__(self)

    def items(self) -> Any:
        """The (key, value) pairs, every value computed."""
        self._resolved()
        return dict.items(self)

    def values(self) -> Any:
        """The values, every one computed."""
        self._resolved()
        return dict.values(self)

    def copy(self) -> dict[Any, Any]:
        """A plain ``dict`` of the computed values."""
        self._resolved()
        return dict(dict.items(self))

    def __eq__(self, other: object) -> bool:
        self._resolved()
        if isinstance(other, LazyDict):
            other._resolved()
        return dict.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self == other

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        self._resolved()
        return dict.__repr__(self)

    def __reduce__(self) -> tuple[Any, ...]:
        return (dict, (self.copy(),))

    def __reduce_ex__(self, protocol: Any) -> tuple[Any, ...]:
        return self.__reduce__()
