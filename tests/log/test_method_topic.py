"""``/method`` messages: the per-signature recipe against the dict path (the oracle)."""

import json
import math

import numpy as np

from amex.log import messages as M
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
    yield {**_first(), "y_star": None, "maybe": 1.5}
    yield {"mode": "grow", "new_key": 1.0, "s": 0.5}  # keys missing, a new one, another order
    yield {"t": 99.0, "s": 0.5}  # a key named t is not the time
    yield {}


def test_the_recipe_gives_the_dict_paths_bytes_for_every_kind_of_value():
    rng = np.random.default_rng(0)
    topic = MethodTopic()
    schema = topic.schema(0.0, _first())
    assert M.viewer_schema_problems(schema) == []
    assert set(topic.kinds) == {"t", "s", "delta_g", "steps", "iters", "converged", "mode",
                                "y_star", "maybe"} - {"maybe"}  # fmt: skip
    for rep in range(3):  # recipes are cached: the second pass reuses them
        for k, internals in enumerate(_variants(rng)):
            t = 0.01 * k + rep
            fast = topic.encode(t, internals)
            assert fast == topic.reference_encode(t, internals), internals
            json.loads(fast)  # strict JSON (no NaN)
    assert topic.encode(math.nan, {"s": 1.0}) == topic.reference_encode(math.nan, {"s": 1.0})


def test_numbers_keep_their_full_precision_and_non_finite_ones_become_null():
    topic = MethodTopic()
    topic.schema(0.0, {"x": 0.1, "v": np.zeros(2)})
    message = json.loads(topic.encode(1.0, {"x": 1 / 3, "v": np.array([math.nan, 2.0])}))
    assert message == {"t": 1.0, "x": 1 / 3, "v": [None, 2.0]}
