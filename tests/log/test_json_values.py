"""The JSON texts of a log's metadata records and messages (amex.log.messages)."""

import enum
import json
import math

import numpy as np

from amex.log.messages import jsonable, metadata_record


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
