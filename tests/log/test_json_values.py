"""The JSON texts of a log's metadata records and messages (amex.log.messages)."""

import enum
import json
import math

import numpy as np

from amex.log.messages import json_text, jsonable, metadata_record


class _Mode(enum.IntEnum):
    FAST = 2


def test_values_become_json_numbers_texts_flags_lists_and_nulls():
    cases = [
        (1.5, 1.5), (-0.0, -0.0), (math.nan, None), (math.inf, None), (-math.inf, None),
        (3, 3), (True, True), (False, False), ("x", "x"), (None, None),
        (np.float64(2.5), 2.5), (np.float32(0.5), 0.5), (np.int64(-4), -4), (_Mode.FAST, 2),
        (np.array([1.0, math.nan]), [1.0, None]), (np.arange(3), [0, 1, 2]),
        ([1, [2.0, math.inf], "a"], [1, [2.0, None], "a"]), ((1, 2.0), [1, 2.0]),
        ({"a": np.float64(1.0), 2: [math.nan]}, {"a": 1.0, "2": [None]}),
        (np.bool_(True), "True"),  # no JSON type of its own: its text
    ]  # fmt: skip
    for value, expected in cases:
        got = jsonable(value)
        assert got == expected and type(got) is type(expected), (value, got)
        json.dumps(got, allow_nan=False)  # valid JSON, no NaN
    assert type(jsonable(3)) is int and type(jsonable(np.int64(3))) is int
    assert math.copysign(1.0, jsonable(-0.0)) == -1.0


def test_a_metadata_record_is_a_json_text_per_key():
    record = metadata_record({"x": np.array([0.5, math.nan]), 3: "a"})
    assert record == {"x": "[0.5, null]", "3": '"a"'}


class _Float(float):
    pass


def test_a_value_s_text_is_json_dumps_of_its_jsonable_form():
    rng = np.random.default_rng(5)
    cases = [
        0.1, 1 / 3, -0.0, 1e300, 5e-324, 2.0**-1074, math.nan, math.inf, -math.inf, _Float(2.5),
        0, 3, -(2**70), 2**64, True, False, None, _Mode.FAST, np.float64(0.3), np.int64(4),
        "", "x", 'a\u00e9\u2028"\\\n\x00\x7f', "\ud800", [1.0, math.nan], np.arange(3.0),
        {"a": 1}, (1, 2), np.bool_(False),
        *(rng.standard_normal(200) * 10.0 ** rng.integers(-300, 300, 200)).tolist(),
    ]  # fmt: skip
    for value in cases:
        assert json_text(value) == json.dumps(jsonable(value)), value
