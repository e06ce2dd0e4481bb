"""``/method`` messages: the per-signature recipe against the general rule (the oracle)."""

import math
import struct

import numpy as np
import pytest

from amex.core.lazy import Lazy, LazyDict
from amex.log.flat_proto import FlatDecoder, descriptor_set, field_names
from amex.log.method_topic import MethodTopic


def _first():
    return {
        "s": 0.25,
        "delta_g": np.float64(0.5),
        "steps": 400,
        "iters": np.int64(3),
        "converged": True,
        "mode": "shrink",
        "y_star": np.array([0.1, 0.2, 0.3]),
        "big": np.zeros(100),
        "flat": np.zeros((2, 2)),
        "maybe": None,
    }


def _variants(rng):
    yield _first()
    yield {**_first(), "s": float(rng.normal()), "y_star": rng.normal(size=3)}
    yield {**_first(), "s": math.nan}  # non-finite: null
    yield {**_first(), "y_star": np.array([1.0, math.inf, 2.0])}
    yield {**_first(), "steps": 2.5, "s": 3}  # another kind: null; an int for a number
    yield {**_first(), "converged": "yes", "mode": 'quo"te\\ ünï'}
    yield {**_first(), "y_star": np.arange(3)}  # an int array
    yield {**_first(), "y_star": np.array([True, False])}  # a bool array: another kind
    yield {**_first(), "y_star": np.zeros(70)}  # too large: left out
    yield {**_first(), "y_star": np.zeros((3, 1))}  # not (k,): left out
    yield {**_first(), "y_star": np.array([], dtype=float)}
    yield {**_first(), "y_star": np.array([1.0, 2.0], dtype=np.float32)}
    yield {**_first(), "y_star": [0.1, 0.2]}  # a list
    yield {**_first(), "y_star": b"\x00" * 24}  # bytes: no array, absent
    yield {**_first(), "y_star": None, "maybe": 1.5}
    yield {"mode": "grow", "new_key": 1.0, "s": 0.5}  # keys missing, a new one, another order
    yield {"t": 99.0, "s": 0.5}  # a key named t is not the time
    # every value a number (one pack): floats, numpy's, ints, non-finite ones, in another order
    yield {"iters": np.int64(-3), "s": math.inf, "delta_g": np.float64(math.nan), "steps": 7}
    yield {"s": 0.25, "delta_g": -0.0, "steps": 2**53 + 1, "iters": 4.5}
    yield {"s": 0.25, "steps": True}  # a flag where a number is: not one pack
    # flags and texts in one pack (CR's steps): multi-byte, empty, 1- and 2-byte lengths
    yield {**_first(), "mode": "ü" * 64, "converged": False}  # 128 bytes
    yield {**_first(), "mode": "x" * 127}
    yield {**_first(), "mode": "x" * 300}
    yield {**_first(), "mode": ""}
    yield {**_first(), "converged": np.bool_(True)}  # numpy's flag: the converters
    yield {}


def test_the_recipe_gives_the_general_rules_bytes_for_every_kind_of_value():
    rng = np.random.default_rng(0)
    topic = MethodTopic()
    schema = topic.schema(0.0, _first())
    assert set(topic.kinds) == {"t", "s", "delta_g", "steps", "iters", "converged", "mode",
                                "y_star", "maybe"} - {"maybe"}  # fmt: skip
    decoder = FlatDecoder(schema.descriptor_set(), schema.name)
    for rep in range(3):  # recipes are cached: the second pass reuses them
        for k, internals in enumerate(_variants(rng)):
            t = 0.01 * k + rep
            fast = topic.encode(t, internals)
            assert fast == topic.reference_encode(t, internals), internals
            assert decoder.decode(fast)["t"] == t
    assert topic.encode(math.nan, {"s": 1.0}) == topic.reference_encode(math.nan, {"s": 1.0})


def test_values_read_back_exactly_and_other_kinds_are_absent():
    topic = MethodTopic()
    schema = topic.schema(0.0, _first())
    decoder = FlatDecoder(schema.descriptor_set(), schema.name)
    read = decoder.decode(topic.encode(1.5, {**_first(), "s": 1 / 3, "steps": 2.5, "iters": 4}))
    assert read == {"t": 1.5, "s": 1 / 3, "delta_g": 0.5, "steps": 2.5, "iters": 4.0,
                    "converged": True, "mode": "shrink", "y_star": [0.1, 0.2, 0.3]}  # fmt: skip
    odd = {"s": math.nan, "delta_g": math.inf, "converged": "yes", "mode": 3.0,
           "y_star": np.array([True, False]), "steps": None, "iters": np.zeros(70)}  # fmt: skip
    read = decoder.decode(topic.encode(2.0, odd))
    assert math.isnan(read["s"]) and read["delta_g"] == math.inf  # exact, not null
    assert read["converged"] is read["mode"] is read["y_star"] is None
    assert read["steps"] is read["iters"] is None
    assert decoder.decode(topic.encode(3.0, {"y_star": np.arange(3)}))["y_star"] == [0, 1, 2]
    assert decoder.decode(topic.encode(3.0, {"y_star": np.zeros(0)}))["y_star"] == []
    assert decoder.decode(topic.encode(3.0, {"mode": 'quo"te ünï'}))["mode"] == 'quo"te ünï'


def test_keys_that_are_no_identifiers_get_field_names_and_damage_is_refused():
    assert field_names(["a b", "a_b", "1x", "t", "ok"], reserved=("t",)) == [
        "a_b",
        "a_b_2",
        "_1x",
        "t_2",
        "ok",
    ]
    topic = MethodTopic()
    schema = topic.schema(0.0, {"a b": 1.0, "t": 5.0})
    assert [name for name, _ in schema.fields] == ["t", "a_b"]
    decoder = FlatDecoder(schema.descriptor_set(), schema.name)
    assert decoder.decode(topic.encode(1.0, {"a b": 2.0, "t": 5.0})) == {"t": 1.0, "a_b": 2.0}
    for damaged in (b"{not json", b"\x09\x00\x00", b"\x1a\x08" + bytes(8), b"\x12\x03abc"):
        with pytest.raises((ValueError, IndexError)):
            decoder.decode(damaged)
    with pytest.raises(ValueError, match="invalid protobuf field name"):
        descriptor_set("amex.X", [("a b", "double")])


def test_a_lazy_value_the_schema_lacks_is_not_computed_for_the_message():
    computed = []

    def plan():
        computed.append(1)
        return np.zeros((50, 3))  # (k, 3): no per-step field

    def step(s):
        return LazyDict(s=s, plan=Lazy(plan), y_star=Lazy(lambda: np.array([s, 0.0, 1.0])))

    topic = MethodTopic()
    topic.schema(0.0, step(0.0))  # the first step reads every value: the schema needs them
    assert set(topic.kinds) == {"t", "s", "y_star"} and computed == [1]
    for k in range(1, 4):
        internals = step(0.1 * k)
        fast = topic.encode(0.01 * k, internals)
        assert len(computed) == k  # the plan stays unread; y_star, in the schema, is computed
        assert fast == topic.reference_encode(0.01 * k, internals)  # reads items(): everything
        assert len(computed) == k + 1


def test_a_step_is_captured_with_its_values_and_encoded_later_as_they_were():
    topic = MethodTopic()
    buffer, values = np.array([0.1, 0.2, 0.3]), [1.0, 2.0]
    internals = {"s": 0.5, "y_star": buffer, "listed": values, "big": np.zeros(100)}
    topic.schema(0.0, internals)
    expected = topic.encode(0.01, internals)
    captured = topic.capture(internals)
    buffer[:] = 9.0  # a method that reuses its buffers for the next step
    values[0] = 9.0
    assert topic.encode_captured(0.01, captured) == expected
    assert topic.encode_captured(0.01, captured) != topic.encode(0.01, internals)


def test_numbers_and_arrays_are_one_pack_with_the_general_rules_bytes():
    """AMEX's steps (numbers and small arrays): one ``struct`` pack per sizes of the arrays."""
    first = {"s": 0.25, "delta_g": np.float64(0.5), "y_star": np.zeros(6), "yd_star": np.ones(6)}
    topic = MethodTopic()
    schema = topic.schema(0.0, first)
    decoder = FlatDecoder(schema.descriptor_set(), schema.name)
    rng = np.random.default_rng(1)
    variants = [
        first,
        {**first, "y_star": rng.normal(size=6), "s": -0.0, "delta_g": np.int64(-7)},
        {**first, "y_star": np.array([math.nan, math.inf, -math.inf, 0.0, -0.0, 1e308])},
        {**first, "y_star": np.arange(4), "yd_star": np.array([2**60, -1])},  # int arrays
        {**first, "y_star": np.array([1.5, 2.25], dtype=np.float32)},
        {**first, "y_star": np.zeros(0)},  # empty: a field of no doubles
        {**first, "y_star": np.zeros(64), "yd_star": np.zeros(65)},  # the largest; too large
        {**first, "y_star": np.zeros((2, 3))},  # not (k,): left out
        {**first, "y_star": np.array([True, False])},  # flags: another kind, left out
        {**first, "y_star": np.zeros(6)[::2]},  # a strided view
        {**first, "s": 3, "y_star": [0.5, 1.5]},  # an int; a list: the converters
    ]
    for rep in range(2):  # the second pass reuses the cached packers
        for k, internals in enumerate(variants):
            t = 0.01 * k + rep
            fast = topic.encode(t, internals)
            assert fast == topic.reference_encode(t, internals), internals
            assert decoder.decode(fast)["t"] == t
    recipe, _ = topic.capture(first)
    assert recipe.packed is None and recipe.vectors is not None
    assert (48, 48) in recipe.vectors  # the arrays' byte sizes
    read = decoder.decode(topic.encode(1.0, variants[3]))
    assert read["y_star"] == [0.0, 1.0, 2.0, 3.0] and read["yd_star"] == [float(2**60), -1.0]


def test_crs_steps_are_one_pack_per_length_of_their_texts():
    first = {"mode": "shrink", "steps": 40, "iterations": 3, "cost": 0.5, "converged": True}
    topic = MethodTopic()
    decoder = FlatDecoder(topic.schema(0.0, first).descriptor_set(), "amex.MethodInternals")
    for t, mode in enumerate(("shrink", "tail", "hold", "tail")):
        step = {**first, "mode": mode, "converged": t % 2 == 0}
        fast = topic.encode(float(t), step)
        assert fast == topic.reference_encode(float(t), step)
        assert decoder.decode(fast)["mode"] == mode
    recipe, _ = topic.capture(first)
    assert recipe.packed is None and sorted(recipe.vectors) == [(4,), (6,)]


def test_a_snapshot_keeps_the_steps_values_and_computes_nothing():
    computed = []
    buffer, values = np.array([0.1, 0.2, 0.3]), [1.0, 2.0]

    def plan():
        computed.append(1)
        return np.zeros((80, 3))

    topic = MethodTopic()
    topic.schema(0.0, {"s": 0.5, "y_star": buffer, "listed": values, "plan": np.zeros((80, 3))})
    internals = LazyDict(s=0.5, y_star=buffer, listed=values, plan=Lazy(plan))
    expected = topic.encode(0.01, {"s": 0.5, "y_star": buffer.copy(), "listed": list(values)})
    snap = topic.snapshot(internals)
    assert not computed  # the lazy plan is not in the schema: never computed for /method
    buffer[:] = 9.0  # a method that reuses its buffers for the next step
    values[0] = 9.0
    assert topic.encode_snapshot(0.01, snap) == expected
    assert not computed
    plain = topic.snapshot({"s": 0.5, "y_star": buffer, "listed": values})
    assert type(plain) is dict and plain["y_star"] is not buffer and plain["listed"] is not values


class _Subclass(np.ndarray):
    pass


def _batches(rng):
    """Batches of steps: uniform ones (one compiled call) and ones that are not."""
    amex = {"s": 0.25, "delta_g": np.float64(0.5), "delta_y": 1.0, "y_star": np.zeros(6),
            "yd_star": np.ones(6)}  # fmt: skip
    yield [{**amex, "s": float(s), "y_star": rng.normal(size=6)} for s in rng.random(50)]
    yield [  # numbers of every number type, non-finite ones, -0.0, ints beyond 2**53
        {**amex, "s": math.nan, "delta_g": np.int64(-7), "delta_y": 2**53 + 1},
        {**amex, "s": -0.0, "delta_g": math.inf, "delta_y": np.float64(-math.inf)},
        {**amex, "s": 3, "y_star": np.array([math.nan, -0.0, 0.0, 1e308, 5e-324, -1.0])},
        {**amex, "y_star": np.arange(6), "yd_star": np.array([2**60, -1, 0, 1, 2, 3])},
        {**amex, "yd_star": np.ones(6, dtype=np.float32) / 3},
        {**amex, "y_star": np.arange(12.0)[::2]},  # a strided view
    ]
    yield [{"phase": float(p), "phase_rate": -float(p)} for p in rng.random(7)]  # the DMP's
    yield [{**amex, "y_star": np.zeros(0), "yd_star": np.zeros(0)}] * 3  # empty arrays
    yield [{**amex, "y_star": np.zeros(64)}] * 2  # the largest array logged
    yield [{"t": 5.0, **amex, "extra": 1.0}] * 2  # a key named t; a key the schema lacks
    yield [{}] * 2
    # not uniform: a step at a time (the same bytes all the same)
    yield [amex, {**amex, "y_star": np.zeros(5)}]  # another size
    yield [amex, {**amex, "y_star": np.zeros(65)}]  # too large: left out
    yield [{**amex, "y_star": np.zeros(65)}] * 2  # too large at every step
    yield [amex, {**amex, "y_star": np.array(0.5)}]  # a scalar array
    yield [{**amex, "y_star": np.zeros((1, 6))}] * 2  # (1, k) at every step
    # three text fields in a row, then a number between texts
    yield [{"mode": m, "other": m * 2, "label": "é" + m, "s": 0.5} for m in ("a", "", "xyz")]
    yield [{"mode": m, "s": j, "other": "-" + m} for j, m in enumerate(("q", "rr", ""))]
    yield [amex, {**amex, "y_star": np.zeros((2, 3))}]  # not (k,)
    yield [amex, {**amex, "y_star": np.array([True] * 6)}]  # flags
    yield [amex, {**amex, "s": None}]
    yield [amex, {**amex, "s": True}]  # a flag where a number is
    yield [amex, {**amex, "s": np.float32(0.5)}]
    yield [amex, {**amex, "y_star": [0.5] * 6}]  # a list
    yield [amex, dict(reversed(list(amex.items())))]  # another order
    yield [amex, {k: v for k, v in amex.items() if k != "s"}]  # a key missing
    yield [amex, {**amex, "s": 2**1100}]  # beyond doubles: as a step alone does
    # a snapshot takes doubles as their bytes: other arrays, and a method's bytes, are not
    yield [amex, {**amex, "y_star": b"\x00" * 48}]  # a method's bytes: no array, absent
    yield [{**amex, "y_star": np.full(6, 1.5, dtype=">f8")}] * 2  # big-endian doubles
    yield [amex, {**amex, "y_star": np.arange(6)}]  # doubles, then ints
    yield [amex, {**amex, "y_star": np.zeros(12)[::2]}]  # a strided view of doubles
    yield [amex, {**amex, "y_star": np.zeros(6).view(_Subclass)}]  # an ndarray subclass
    # CR's: texts and flags, of every length (1- and 2-byte varints), multi-byte, empty
    cr = {"mode": "tail", "steps": 40, "converged": True, "cost": 0.5}
    texts = ["shrink", "", "ü" * 64, "x" * 127, "x" * 300, "hold", "€", "tail"]
    yield [{**cr, "mode": m, "converged": j % 3 == 0} for j, m in enumerate(texts)]
    yield [{**cr, "mode": "a", "other": "b" * 200}, {**cr, "mode": "", "other": ""}]
    yield [cr, {**cr, "converged": np.bool_(True)}]  # numpy's flag: a step at a time
    yield [cr, {**cr, "converged": 1}]  # a number where a flag is
    yield [cr, {**cr, "mode": "\udc80"}]  # a lone surrogate: as a step alone does
    yield [cr, {**cr, "mode": None}]
    yield [LazyDict(cr), LazyDict({**cr, "mode": "grow"})]  # lazy dicts: CR's
    yield [LazyDict({**cr, "plan": Lazy(lambda: np.zeros((400, 3)))})] * 2  # one not logged


def test_a_batch_is_encoded_as_each_step_alone():
    rng = np.random.default_rng(7)
    for batch in _batches(rng):
        topic = MethodTopic()
        first = {"mode": "", "converged": False, "other": "", "label": "",
                 **dict(dict.items(batch[0]))}  # fmt: skip
        first["s"] = 0.0
        topic.schema(0.0, {k: v for k, v in first.items() if not isinstance(v, Lazy)})
        times = [0.01 * (j + 1) for j in range(len(batch))]
        try:
            snaps = [topic.snapshot(step) for step in batch]
            alone = [topic.encode_snapshot(t, s) for t, s in zip(times, snaps, strict=True)]
        except (OverflowError, TypeError, UnicodeEncodeError, struct.error) as error:
            with pytest.raises(type(error)):
                topic.encode_snapshots(times, [topic.snapshot(step) for step in batch])
            continue
        together = topic.encode_snapshots(times, [topic.snapshot(step) for step in batch])
        assert together == alone, batch[:2]
        for t, step, data in zip(times, batch, together, strict=True):
            assert data == topic.reference_encode(t, step)
        # a fresh method's internals themselves, no snapshots: the same messages
        assert topic.encode_snapshots(times, list(batch), raw=True) == together


def test_a_uniform_batch_takes_the_compiled_call(monkeypatch):
    import amex.log.method_topic as MT

    cr = [LazyDict(mode=m, steps=j, ok=j > 1, plan=Lazy(list)) for j, m in enumerate("ab")]
    topic = MethodTopic()
    topic.schema(0.0, {"mode": "", "steps": 0, "ok": True})
    calls = []
    monkeypatch.setattr(MT.MethodTopic, "encode_snapshot", lambda *a: calls.append(a))
    assert len(topic.encode_snapshots([0.0, 1.0], [topic.snapshot(step) for step in cr])) == 2
    assert not calls  # CR's steps: texts, numbers and flags of lazy dicts
    topic = MethodTopic()
    steps = [{"s": 0.1 * j, "y_star": np.full(3, float(j))} for j in range(5)]
    topic.schema(0.0, steps[0])
    out = topic.encode_snapshots([0.0, 1.0, 2.0, 3.0, 4.0], steps)
    assert not calls and len(out) == 5
    snaps = [topic.snapshot(step) for step in steps]  # their doubles as bytes
    assert type(snaps[0]["y_star"]) is bytes
    assert topic.encode_snapshots([0.0, 1.0, 2.0, 3.0, 4.0], snaps) == out and not calls
    decoder = FlatDecoder(topic.schema(0.0, steps[0]).descriptor_set(), "amex.MethodInternals")
    assert decoder.decode(out[3]) == {"t": 3.0, "s": 0.1 * 3, "y_star": [3.0] * 3}


def test_a_fresh_methods_bytes_are_no_array():
    topic = MethodTopic()
    topic.schema(0.0, {"s": 0.5, "y_star": np.zeros(6)})
    steps = [{"s": 0.5, "y_star": b"\x01" * 48}] * 3  # bytes at every step: absent
    times = [0.0, 0.1, 0.2]
    raw = topic.encode_snapshots(times, steps, raw=True)
    assert raw == [topic.reference_encode(t, step) for t, step in zip(times, steps, strict=True)]
    schema = topic.schema(0.0, {"s": 0.5, "y_star": np.zeros(6)})
    decoder = FlatDecoder(schema.descriptor_set(), "amex.MethodInternals")
    assert decoder.decode(raw[0])["y_star"] is None


def test_a_batch_of_arrays_the_schema_does_not_take_is_encoded_as_each_step_alone():
    # the schema is the first step's: later batches may all have arrays it does not log
    for later in (np.zeros((1, 6)), np.zeros(65), np.arange(6), np.zeros(12)[::2], np.array(2.0)):
        topic = MethodTopic()
        topic.schema(0.0, {"s": 0.5, "y_star": np.zeros(6)})
        steps = [{"s": 0.1 * j, "y_star": later} for j in range(3)]
        times = [0.0, 0.1, 0.2]
        alone = [topic.reference_encode(t, step) for t, step in zip(times, steps, strict=True)]
        assert topic.encode_snapshots(times, steps, raw=True) == alone, later
        snaps = [topic.snapshot(step) for step in steps]
        assert topic.encode_snapshots(times, snaps) == alone, later
