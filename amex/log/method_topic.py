"""The ``/method`` topic of a log: a method's ``internals()`` at every outer step, as protobuf.

The channel and its schema are made at the first step from the values then: ``t`` (field 1),
then one field per key whose value has a kind (:func:`amex.log.messages.value_schema`), in the
order of the keys: a number is a ``double``, a flag a ``bool``, a text a ``string``, a number
array of at most :data:`MAX_ARRAY` entries and shape (k,) a ``repeated double``
(:class:`amex.log.flat_proto.FlatSchema`; a key that is no identifier gets a field name made
from it, :func:`~amex.log.flat_proto.field_names`). Numbers are written exactly (NaN and
infinity too; ints as doubles). Later, a key the schema lacks is left out, and so is a value of
another kind, None, and an array of more entries or of another shape: an absent field, which
the reader gives as None.

:meth:`MethodTopic.encode` writes a step through a recipe made once per combination of keys and
value types: one converter per key, the common types' without a type test (~1.5 us for AMEX's
15 numbers; their shortest texts took ~15 us). Where every value is a number (the DMP's steps),
the recipe is one ``struct`` pack of ``t`` and all the fields, keys included: the same bytes as
the converters' concatenation. Where every value is a number, a flag, a text or a small array
(AMEX's steps, CR's), it is one pack per the arrays' sizes and the texts' lengths. A logger
encodes a batch of steps at a time (:meth:`MethodTopic.encode_snapshots`): where every step has
the same keys and only numbers, flags, texts and arrays of one size each (AMEX's, the DMP's,
CR's), in one compiled call (:func:`encode_flat_rows`), the same bytes.
:meth:`MethodTopic.reference_encode` converts each value by the general rule (:func:`_encoded`),
the oracle (tests/log/test_method_topic.py compares them).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from itertools import chain
from typing import Any, NamedTuple

import numba
import numpy as np

from amex.core.lazy import LazyDict
from amex.log import flat_proto as P
from amex.log import messages as M
from amex.log.wire import double_field, varint_field

MAX_ARRAY = 64  # entries of the largest array that is logged per step

#: The protobuf kind of each schema kind of :func:`amex.log.messages.value_schema`.
_PROTO_KIND = {"number": "double", "boolean": "bool", "string": "string", "array": "doubles"}

Converter = Callable[[Any], bytes]  # a value's field (key included), b"": absent
_NUMBER_TYPES = (float, np.float64, int, np.int64)  # written as doubles without a type test
# The forms of a value in a one-pack message (Recipe.fields): a double, a packed field of
# doubles, a flag's byte, a text's UTF-8 bytes.
_NUMBER, _ARRAY, _FLAG, _TEXT = range(4)
_RAW = 4  # a snapshot's array of doubles, as their bytes (MethodTopic.snapshot)
_F8 = np.dtype(np.float64)


class Recipe(NamedTuple):
    """How the steps of one combination of keys and value types are encoded (module notes).

    Attributes:
        converters: per value, its field's converter.
        arrays: the indices of the values that are arrays or lists (copied when captured).
        packed: where every value is a number, the message's ``struct`` (``t``, then each
            field's key and double), else None.
        arguments: the pack's arguments with the keys in place (``t`` and the values as 0.0).
        fields: per value, its field's key and its form in one pack (``_NUMBER``, ``_ARRAY``,
            ``_FLAG``, ``_TEXT``).
        vectors: where every value is a number, an array, a flag or a text (AMEX's, CR's
            steps), the message's ``struct`` and its arguments' template per byte sizes of the
            arrays (each a packed field of doubles) and texts, made at the first step of those
            sizes; else None.
        sized: the indices of the arrays and texts among the values, for :attr:`vectors`.
    """

    converters: tuple[Converter, ...]
    arrays: tuple[int, ...]
    packed: struct.Struct | None
    arguments: tuple[Any, ...]
    fields: tuple[tuple[bytes, int], ...] = ()
    vectors: dict[tuple[int, ...], tuple[struct.Struct, tuple[Any, ...]]] | None = None
    sized: tuple[int, ...] = ()


#: A step's values to encode: their recipe and the values (:meth:`MethodTopic.capture`).
Captured = tuple[Recipe, list[Any]]


def _kind_of(value: Any) -> str | None:
    """The schema kind (``number``, ``array``, ...) of one value, None if it has none."""
    schema = M.value_schema(value)
    return None if schema is None else schema["type"]


class MethodTopic:
    """The schema and the messages of ``/method`` (module notes).

    Attributes:
        kinds: per key of the first step (and ``t``), its schema kind; None before :meth:`schema`.
    """

    def __init__(self) -> None:
        self.kinds: dict[str, str] | None = None
        self._keys: dict[str, bytes] = {}  # key -> its field's key bytes
        self._recipes: dict[tuple[Any, ...], Recipe] = {}
        self._snapshot_recipes: dict[tuple[Any, ...], Recipe] = {}  # bytes: an array's doubles
        self._logged: dict[tuple[str, ...], tuple[str, ...]] = {}  # a step's keys -> logged ones
        self._array_keys: tuple[str, ...] = ()  # the schema's keys of kind "array"

    def schema(self, t: float, internals: dict[str, Any]) -> P.FlatSchema:
        """The channel's schema, from the first step's values (sets :attr:`kinds`)."""
        kinds = {"t": "number"}
        for key, value in internals.items():
            if key == "t":
                continue  # the step's time, not the method's
            if isinstance(value, np.ndarray):
                if value.size > MAX_ARRAY or value.ndim != 1:
                    continue  # large arrays do not belong in a per-step message
                value = value.tolist()
            kind = _kind_of(value)
            if kind is not None:
                kinds[key] = kind
        keys = [k for k in kinds if k != "t"]
        names = P.field_names(keys, reserved=("t",))
        fields = [("t", "double")]
        fields += [(n, _PROTO_KIND[kinds[k]]) for k, n in zip(keys, names, strict=True)]
        self._keys = {
            k: P.tag(number, _PROTO_KIND[kinds[k]]) for number, k in enumerate(keys, start=2)
        }
        self.kinds = kinds
        self._array_keys = tuple(k for k in keys if kinds[k] == "array")
        return P.FlatSchema("amex.MethodInternals", tuple(fields))

    def encode(self, t: float, internals: dict[str, Any]) -> bytes:
        """The message of one step (after :meth:`schema`); equal to :meth:`reference_encode`.

        :meth:`capture`, then :meth:`encode_captured`. Only the schema's keys are read: a
        :class:`~amex.core.lazy.LazyDict` value the schema lacks (CR's planned path, a large
        array) is not computed for ``/method``.
        """
        return self.encode_captured(t, self.capture(internals))

    def capture(self, internals: dict[str, Any], *, copy: bool = True) -> Captured:
        """What a step's message needs, taken now and encoded later (:meth:`encode_captured`).

        The values of the schema's keys, lists and arrays copied (a method may reuse its
        buffers), and the recipe of their keys and types. A logger runs this at every step,
        right after the method's step, and the encoding with the batch (``amex.log.writer``),
        where it runs warm: encoded between the inner steps, AMEX's message cost ~15 us a step,
        three times its time in a loop (issue #29).
        """
        return self._capture(internals, copy, snapshot=False)

    def _capture(self, internals: dict[str, Any], copy: bool, *, snapshot: bool) -> Captured:
        """:meth:`capture`; of a :meth:`snapshot`'s values (its doubles' bytes) if ``snapshot``."""
        keys = tuple(internals)
        try:
            logged = self._logged[keys]
        except KeyError:
            logged = self._logged[keys] = self._logged_keys(keys)
        values = list(internals.values()) if logged is keys else [internals[k] for k in logged]
        signature = (logged, tuple(map(type, values)))
        recipes = self._snapshot_recipes if snapshot else self._recipes
        try:
            recipe = recipes[signature]
        except KeyError:
            recipe = recipes[signature] = self._recipe(*signature, snapshot=snapshot)
        if copy:
            for i in recipe.arrays:  # lists and small arrays are copied; larger ones left out
                value = values[i]
                if type(value) is list or value.size <= MAX_ARRAY:
                    values[i] = value.copy()
        return recipe, values

    def snapshot(self, internals: dict[str, Any]) -> dict[str, Any]:
        """What a step's message needs, taken now at the least cost; encoded later.

        A shallow copy of the dict (a :class:`~amex.core.lazy.LazyDict`'s lazy values stay
        lazy: they are snapshots of their own), with the small arrays and lists of the schema's
        array keys copied (a method may reuse its buffers): an array of doubles of shape (k,)
        as its doubles' bytes (``tobytes``, a third of a copy's time, and the field's data), a
        method's own ``bytes`` there as None (they are no array: absent either way); numbers,
        flags and texts are immutable. :meth:`encode_snapshot` turns it into the message with
        the batch, where it runs warm: between the inner steps, :meth:`capture` cost ~8 us a
        step, about four times its time in a loop (issue #29).
        """
        if type(internals) is dict:
            snap = internals.copy()
        elif isinstance(internals, LazyDict):
            snap = LazyDict(dict.items(internals))  # the raw values: nothing computed here
        else:
            snap = dict(internals)
        for key in self._array_keys:
            value = snap.get(key)
            if type(value) is np.ndarray and value.dtype is _F8 and value.ndim == 1:
                if value.size <= MAX_ARRAY:  # its doubles' bytes: the copy and the field's data
                    snap[key] = value.tobytes()
            elif type(value) is list or (isinstance(value, np.ndarray) and value.size <= MAX_ARRAY):
                snap[key] = value.copy()
            elif type(value) is bytes:  # no array (absent): not to be taken for one's doubles
                snap[key] = None
        return snap

    def encode_snapshot(self, t: float, snap: dict[str, Any]) -> bytes:
        """The message of a step at time ``t`` [s] from its :meth:`snapshot`."""
        return self.encode_captured(t, self._capture(snap, False, snapshot=True))

    def encode_snapshots(
        self, times: list[float], snaps: list[dict[str, Any]], *, raw: bool = False
    ) -> list[bytes]:
        """:meth:`encode_snapshot` of each step of a batch: the same bytes, in one compiled call.

        Where every step has the first step's keys in its order and each logged value is, at
        every step, a number of one of the number types, a flag (``bool``), a text (``str``) or
        a number array of shape (k,), k <= :data:`MAX_ARRAY`, the same k at every step (AMEX's,
        the DMP's, CR's steps): the values are gathered a key at a time (:class:`FlatRows`) and
        the messages written by :func:`encode_flat_rows`, ~0.5 us a step against ~4.7 us for
        AMEX's alone. Any other batch (None, numpy's flags, another size) is encoded a step at
        a time. ``raw``: the steps are the method's ``internals()`` themselves, no snapshots (a
        method of :attr:`~amex.methods.base.Method.fresh_steps`): ``bytes`` are no doubles.
        """
        rows = self._flat_rows(snaps, raw)
        if rows is None:
            return [
                self.encode_captured(t, self._capture(snap, False, snapshot=not raw))
                for t, snap in zip(times, snaps, strict=True)
            ]
        k = len(snaps)
        sizes = [9 if n < 0 else 10 + 8 * n for n in rows.counts.tolist()]  # and the keys
        row = 9 + (int(rows.key_ends[-1]) if len(rows.key_ends) else 0) + sum(sizes)
        out = np.empty(k * row + len(rows.texts), dtype=np.uint8)
        bounds = np.empty(k + 1, dtype=np.int64)
        encode_flat_rows(np.asarray(times, dtype=float), *rows, out, bounds)
        data = out[: bounds[k]].tobytes()
        edges = bounds.tolist()
        return [data[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]

    def _flat_rows(self, snaps: list[dict[str, Any]], raw: bool = False) -> FlatRows | None:
        """A batch's fields and values for :func:`encode_flat_rows`; None if it has none."""
        if not snaps:
            return None
        keys = tuple(snaps[0])
        for snap in snaps:
            if type(snap) not in _DICTS or tuple(snap) != keys:
                return None  # another kind of dict, or other keys: a step at a time
        try:
            logged = self._logged[keys]
        except KeyError:
            logged = self._logged[keys] = self._logged_keys(keys)
        kinds = self.kinds or {}
        k = len(snaps)
        columns, counts, fields, key_ends = [], [], b"", []
        texts: list[list[bytes]] = []
        for key in logged:
            column = [snap[key] for snap in snaps]
            types = set(map(type, column))
            kind = kinds[key]
            if kind == "number" and types <= _NUMBER_SET:
                try:
                    columns.append(np.array(column, dtype=float).reshape(k, 1))
                except OverflowError:  # an int beyond doubles: as a step alone does
                    return None
                counts.append(_NUMBER_COUNT)
            elif kind == "boolean" and types == _FLAG_SET:
                columns.append(np.array(column, dtype=float).reshape(k, 1))
                counts.append(_FLAG_COUNT)
            elif kind == "string" and types == _TEXT_SET:
                try:
                    texts.append([text.encode() for text in column])
                except UnicodeEncodeError:  # (a lone surrogate) as a step alone does
                    return None
                counts.append(_TEXT_COUNT)
            elif kind == "array" and types == _BYTES_SET and not raw:  # a snapshot's doubles
                sizes = set(map(len, column))
                if len(sizes) != 1:
                    return None
                (size,) = sizes
                columns.append(np.frombuffer(b"".join(column)).reshape(k, size // 8))
                counts.append(size // 8)
            elif kind == "array" and types == _ARRAY_SET and (flat := _doubles(column)) is not None:
                sizes = set(map(len, column))  # (all of one dimension)
                if len(sizes) != 1:
                    return None
                (size,) = sizes
                if size > MAX_ARRAY:
                    return None
                columns.append(flat.reshape(k, size))
                counts.append(size)
            elif kind == "array" and types == _ARRAY_SET:
                shapes, dtypes = {a.shape for a in column}, {a.dtype for a in column}
                if len(shapes) != 1 or any(d.kind not in "fiu" for d in dtypes):
                    return None
                (shape,) = shapes
                if len(shape) != 1 or shape[0] > MAX_ARRAY:
                    return None
                columns.append(np.concatenate(column, dtype=float).reshape(k, shape[0]))
                counts.append(shape[0])
            else:
                return None
            fields += self._keys[key]
            key_ends.append(len(fields))
        values = np.concatenate(columns, axis=1) if columns else np.zeros((k, 0))
        if texts:  # row by row, the fields' texts in order
            ordered = texts[0] if len(texts) == 1 else [*chain(*zip(*texts, strict=True))]
            blob = b"".join(ordered)
            lengths = np.fromiter(map(len, ordered), dtype=np.int64, count=len(ordered))
            text_ends = np.cumsum(lengths).reshape(k, len(texts))
        else:
            blob, text_ends = b"", np.zeros((k, 0), dtype=np.int64)
        return FlatRows(
            np.ascontiguousarray(values),
            np.frombuffer(blob, dtype=np.uint8) if blob else np.zeros(0, dtype=np.uint8),
            np.ascontiguousarray(text_ends, dtype=np.int64),
            np.frombuffer(fields, dtype=np.uint8) if fields else np.zeros(0, dtype=np.uint8),
            np.array(key_ends, dtype=np.int64),
            np.array(counts, dtype=np.int64),
        )

    def encode_captured(self, t: float, captured: Captured) -> bytes:
        """The message of a step at time ``t`` [s] from its :meth:`capture`."""
        recipe, values = captured
        if recipe.packed is not None:  # every value a number: one pack
            arguments = list(recipe.arguments)
            arguments[1] = t
            arguments[3::2] = values
            return recipe.packed.pack(*arguments)
        if recipe.vectors is not None:  # numbers and arrays: one pack where the arrays allow
            packed = _vector_pack(recipe, t, values)
            if packed is not None:
                return packed
        parts = [b"\x09" + P.DOUBLE.pack(t)]
        parts += [convert(value) for convert, value in zip(recipe.converters, values, strict=True)]
        return b"".join(parts)

    def _logged_keys(self, keys: tuple[str, ...]) -> tuple[str, ...]:
        """The keys of ``keys`` the schema has, in their order (``keys`` itself if all)."""
        logged = tuple(k for k in keys if k in self._keys)
        return keys if logged == keys else logged

    def reference_encode(self, t: float, internals: dict[str, Any]) -> bytes:
        """The message of one step, each value converted by the general rule (the oracle)."""
        kinds = self.kinds
        if kinds is None:
            raise ValueError("MethodTopic.schema must be called first")
        parts = [b"\x09" + P.DOUBLE.pack(t)]
        for key, value in internals.items():
            if key in self._keys:
                parts.append(_encoded(self._keys[key], kinds[key], value))
        return b"".join(parts)

    def _recipe(
        self, keys: tuple[str, ...], types: tuple[type, ...], *, snapshot: bool = False
    ) -> Recipe:
        """The :class:`Recipe` of steps of these keys (all of the schema's) and value types.

        Of a :meth:`snapshot`'s values if ``snapshot``: ``bytes`` under an array's key are its
        doubles (a method's own ``bytes`` the snapshot made None).
        """
        kinds = self.kinds or {}
        converters = tuple(
            _converter(self._keys[key], kinds[key], value_type, snapshot)
            for key, value_type in zip(keys, types, strict=True)
        )
        arrays = tuple(i for i, kind in enumerate(types) if kind is np.ndarray or kind is list)
        forms = [
            _form(kinds[key], value_type, snapshot)
            for key, value_type in zip(keys, types, strict=True)
        ]
        if any(form != _NUMBER for form in forms):
            if None in forms:  # some value has no form in one pack: the converters
                return Recipe(converters, arrays, None, ())
            fields = tuple(
                (self._keys[key], form) for key, form in zip(keys, forms, strict=True)
                if form is not None
            )  # fmt: skip
            sized = tuple(i for i, form in enumerate(forms) if form in _SIZED)
            return Recipe(converters, arrays, None, (), fields, {}, sized)
        pairs = [(b"\x09", 0.0)] + [(self._keys[key], 0.0) for key in keys]
        packed = struct.Struct("<" + "".join(f"{len(key)}sd" for key, _ in pairs))
        arguments = tuple(x for pair in pairs for x in pair)
        return Recipe(converters, arrays, packed, arguments)


_NUMBER_SET = frozenset(_NUMBER_TYPES)
_SIZED = (_ARRAY, _TEXT, _RAW)  # the forms packed with their byte lengths
_FLAG_SET, _TEXT_SET, _ARRAY_SET = frozenset((bool,)), frozenset((str,)), frozenset((np.ndarray,))
_BYTES_SET = frozenset((bytes,))
_DICTS = (dict, LazyDict)
# FlatRows.counts of the fields that are no arrays
_NUMBER_COUNT, _FLAG_COUNT, _TEXT_COUNT = -1, -2, -3


def _doubles(column: list[np.ndarray]) -> np.ndarray | None:
    """The arrays of ``column`` one after the other, if all are native doubles of one dimension.

    One concatenation without a cast (a quarter of the time of the shapes' and the dtypes'
    checks, AMEX's batch); None for any other column, which the general checks take.
    """
    try:
        flat = np.concatenate(column, dtype=_F8, casting="no")
    except (TypeError, ValueError):  # another dtype or byte order; a scalar array; mixed shapes
        return None
    return flat if flat.ndim == 1 else None


class FlatRows(NamedTuple):
    """A batch of ``/method`` messages of one layout (:meth:`MethodTopic.encode_snapshots`).

    Attributes:
        values: per row, the numbers, flags (0.0 or 1.0) and the arrays' entries in field
            order, shape (rows, d).
        texts: the texts' UTF-8 bytes, row by row, each row's in field order.
        text_ends: where each row's texts end in ``texts``, shape (rows, texts per row).
        keys: the fields' key bytes, one after the other.
        key_ends: where each field's key ends in ``keys``, shape (fields,).
        counts: per field, an array's length, or -1 (a number), -2 (a flag), -3 (a text).
    """

    values: np.ndarray
    texts: np.ndarray
    text_ends: np.ndarray
    keys: np.ndarray
    key_ends: np.ndarray
    counts: np.ndarray


@numba.njit(cache=True)
def encode_flat_rows(
    times: np.ndarray,
    values: np.ndarray,
    texts: np.ndarray,
    text_ends: np.ndarray,
    keys: np.ndarray,
    key_ends: np.ndarray,
    counts: np.ndarray,
    out: np.ndarray,
    bounds: np.ndarray,
) -> None:
    """Each row's message (:class:`FlatRows`): ``t``, then per field its key and its value.

    The bytes of :meth:`MethodTopic.encode_snapshot`: ``t`` as field 1 (``0x09`` and 8
    little-endian bytes), then each field's key bytes and a number's 8 bytes, a flag's byte,
    a text's varint length and bytes, an array's varint byte length and doubles.

    Args:
        times: the steps' times [s], shape (rows,).
        values: :attr:`FlatRows.values`.
        texts: :attr:`FlatRows.texts`.
        text_ends: :attr:`FlatRows.text_ends`.
        keys: :attr:`FlatRows.keys`.
        key_ends: :attr:`FlatRows.key_ends`.
        counts: :attr:`FlatRows.counts`.
        out: the buffer (large enough).
        bounds: set to where each row's message starts, and the end, shape (rows + 1,).
    """
    scratch = np.empty(1)
    raw = scratch.view(np.uint8)
    i = 0
    text = 0  # the next text's start in texts
    for r in range(len(times)):
        bounds[r] = i
        i = double_field(out, i, 0x09, times[r], scratch)
        column = 0
        start = 0
        t = 0  # the row's texts so far
        for f in range(len(key_ends)):
            for b in range(start, key_ends[f]):
                out[i] = keys[b]
                i += 1
            start = key_ends[f]
            n = counts[f]
            if n == -2:  # a flag
                out[i] = 1 if values[r, column] != 0.0 else 0
                i += 1
                column += 1
                continue
            if n == -3:  # a text
                end = text_ends[r, t]
                i = varint_field(out, i, end - text)
                for b in range(text, end):
                    out[i] = texts[b]
                    i += 1
                text = end
                t += 1
                continue
            if n == -1:  # a number
                n = 1
            else:  # an array: its byte length first
                i = varint_field(out, i, 8 * n)
            for _ in range(n):
                scratch[0] = values[r, column]
                for b in range(8):
                    out[i + b] = raw[b]
                i += 8
                column += 1
    bounds[len(times)] = i


def _form(kind: str, value_type: type, snapshot: bool = False) -> int | None:
    """A value's form in a one-pack message (:data:`_NUMBER`, ...), None if it has none.

    ``snapshot``: the value is a :meth:`MethodTopic.snapshot`'s (``bytes``: an array's doubles).
    """
    if kind == "number" and value_type in _NUMBER_TYPES:
        return _NUMBER
    if kind == "array" and value_type is np.ndarray:
        return _ARRAY
    if kind == "array" and value_type is bytes and snapshot:
        return _RAW
    if kind == "boolean" and value_type is bool:
        return _FLAG
    if kind == "string" and value_type is str:
        return _TEXT
    return None


def _vector_pack(recipe: Recipe, t: float, values: list[Any]) -> bytes | None:
    """The message of numbers, arrays, flags and texts as one ``struct`` pack.

    None (the converters' case) where an array is not (k,) of at most :data:`MAX_ARRAY`
    numbers (the converters then leave it out). The same bytes as the converters': ``t``, then
    each number's key and double, each array's key, byte length and doubles
    (``astype("<f8").tobytes()``: an int array's as doubles), each flag's key and byte, each
    text's key, byte length and UTF-8 bytes. Arrays and texts go into the pack as bytes, so the
    pack has two arguments per field whatever the arrays' sizes.
    """
    values = list(values)
    sizes = []
    for i in recipe.sized:  # the arrays and texts, in order
        value = values[i]
        if type(value) is str:
            data = value.encode()
        elif type(value) is bytes:  # a snapshot's doubles
            data = value
        else:
            if value.ndim != 1 or value.size > MAX_ARRAY or value.dtype.kind not in "fiu":
                return None
            data = value.astype("<f8", copy=False).tobytes()
        values[i] = data
        sizes.append(len(data))
    vectors = recipe.vectors
    assert vectors is not None
    key = tuple(sizes)
    try:
        packer, template = vectors[key]
    except KeyError:
        packer, template = vectors[key] = _vector_packer(recipe.fields, key)
    arguments = list(template)
    arguments[1] = t
    arguments[3::2] = values
    return packer.pack(*arguments)


def _vector_packer(
    fields: tuple[tuple[bytes, int], ...], sizes: tuple[int, ...]
) -> tuple[struct.Struct, tuple[Any, ...]]:
    """The ``struct`` of :func:`_vector_pack` for arrays and texts of ``sizes`` bytes.

    And its arguments' template: ``t``'s key, then per field its prefix (its key, and the byte
    length of an array or text), each followed by a place for the value.
    """
    layout, template, size = ["<1sd"], [b"\x09", 0.0], iter(sizes)
    for key, form in fields:
        if form in _SIZED:
            n = next(size)
            prefix = key + P.varint(n)
            value = f"{n}s"
        else:
            prefix = key
            value = "?" if form == _FLAG else "d"
        layout.append(f"{len(prefix)}s{value}")
        template += [prefix, None]
    return struct.Struct("".join(layout)), tuple(template)


def _absent(value: Any) -> bytes:
    return b""


def _converter(key: bytes, kind: str, value_type: type, snapshot: bool = False) -> Converter:
    """The converter of values of ``value_type`` under a schema ``kind`` (field key ``key``).

    ``snapshot``: of a :meth:`MethodTopic.snapshot`'s values (``bytes``: an array's doubles).
    """
    if value_type is type(None):
        return _absent
    if kind == "number" and value_type in _NUMBER_TYPES:
        double = struct.Struct(f"<{len(key)}sd")
        return lambda value: double.pack(key, value)
    if kind == "boolean" and value_type is bool:
        yes, no = key + b"\x01", key + b"\x00"
        return lambda value: yes if value else no
    if kind == "array" and value_type is np.ndarray:
        return lambda value: _array(key, value)
    if kind == "array" and value_type is bytes and snapshot:
        return lambda value: key + P.varint(len(value)) + value
    return lambda value: _encoded(key, kind, value)  # texts, other types: the general rule


def _array(key: bytes, value: np.ndarray) -> bytes:
    """A number array's field; b"" if it is too large, not (k,), or of no numbers."""
    if value.size > MAX_ARRAY or value.ndim != 1 or value.dtype.kind not in "fiu":
        return b""
    data = value.astype("<f8", copy=False).tobytes()
    return key + P.varint(len(data)) + data


def _encoded(key: bytes, kind: str, value: Any) -> bytes:
    """``value``'s field under a schema ``kind``; b"" (absent) if it is not of that kind."""
    if kind == "array" and isinstance(value, np.ndarray):
        return _array(key, value)
    if isinstance(value, np.ndarray):
        return b""  # an array where the schema has no array: another kind
    if _kind_of(value) != kind:
        return b""  # None, or another kind
    if kind == "number":
        return key + P.DOUBLE.pack(float(value))
    if kind == "boolean":
        return key + (b"\x01" if value else b"\x00")
    if kind == "string":
        data = value.encode()
        return key + P.varint(len(data)) + data
    return _array(key, np.asarray(value, dtype=float))  # a list or tuple of numbers
