"""AMEX's compiled update against its numpy oracle (``update_reference``), bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from amex.core.errors import InputError
from amex.methods.amex import AMEX, AMEXConfig, target_internals
from amex.methods.base import Observation
from amex.plan.reference import ReferencePlan


def _reference(seed: int, m: int = 6, n: int = 401) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = np.linspace(0.0, 1.0, n)[:, None]
    u = 10 * p**3 - 15 * p**4 + 6 * p**5
    bumps = sum(rng.normal(0, 0.05, m) * np.sin(k * np.pi * u) for k in (1, 2, 3))
    return rng.normal(size=m) + u * rng.normal(size=m) + bumps


def _pair(Y, **params):
    plan = ReferencePlan.from_path(Y, 4.0)
    return AMEX(plan, AMEXConfig(**params), 0.01), AMEX(plan, AMEXConfig(**params), 0.01)


def _same(a: AMEX, b: AMEX, ta, tb) -> bool:
    return (
        np.array_equal(ta.y_star, tb.y_star)
        and np.array_equal(ta.yd_star, tb.yd_star)
        and (ta.s, ta.delta_g, ta.delta_y) == (tb.s, tb.delta_g, tb.delta_y)
        and np.array_equal(a.plan.p, b.plan.p)
        and np.array_equal(a.plan.q, b.plan.q)
        and (a.s, a.final_approach) == (b.s, b.final_approach)
    )


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("eq9", ["secant", "tangent"])
@pytest.mark.parametrize("n_control", [0, 40])
def test_compiled_update_equals_the_numpy_oracle_bit_for_bit(seed, eq9, n_control):
    Y = _reference(seed)
    fast, oracle = _pair(Y, eq9=eq9, n_control=n_control)
    rng = np.random.default_rng(seed)
    y, g = Y[0].copy(), Y[-1] + rng.normal(0, 0.05, 6)
    for k in range(700):  # past s = 1: the final approach too
        ta, tb = fast.update(y, g), oracle.update_reference(y, g)
        assert _same(fast, oracle, ta, tb), f"step {k}"
        lag = 0.5 if k % 7 == 0 else 1.0  # a robot that sometimes lags
        y = y + lag * (ta.y_star - y) + rng.normal(0, 1e-4, 6) * (k % 5 == 0)
        g = g + rng.normal(0, 2e-3, 6) * (k < 250)  # a goal that moves, then rests
    assert fast.final_approach


def test_a_changed_config_changes_the_compiled_update_as_the_oracle():
    Y = _reference(9)
    for params in ({"rate_max": 1.5}, {"warmup_steps": 0}, {"end_fraction": 0.0}):
        fast, oracle = _pair(Y, **params)
        for _ in range(50):
            ta, tb = fast.update(Y[5], Y[-1]), oracle.update_reference(Y[5], Y[-1])
            assert _same(fast, oracle, ta, tb)


def test_step_internals_and_restart_match_the_oracle():
    Y = _reference(3)
    fast, oracle = _pair(Y)
    obs = Observation(0.0, np.zeros(7), np.zeros(7), Y[0].copy(), np.zeros(6), Y[-1] + 0.01)
    for amex in (fast, oracle):
        amex.reset(obs)
    assert fast.internals() == oracle.internals()  # before the first update
    _same_internals(fast.internals(), target_internals(None, fast.s))
    for k in range(30):
        command = fast.step(dataclasses.replace(obs, t=0.01 * k))
        _same_internals(fast.internals(), target_internals(fast._target(), fast.s))
        target = oracle.update_reference(obs.y, obs.goal)
        np.testing.assert_array_equal(command.y, target.y_star)
        np.testing.assert_array_equal(command.yd, target.yd_star)
    a, b = fast.internals(), oracle.internals()
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    fast.restart()
    oracle.restart()
    assert _same(fast, oracle, fast.update(Y[0], Y[-1]), oracle.update_reference(Y[0], Y[-1]))


def _same_internals(a, b):
    """The same keys in the same order, each value of the same type and bits."""
    assert list(a) == list(b)
    for key in a:
        assert type(a[key]) is type(b[key]), key
        if isinstance(a[key], np.ndarray):
            assert a[key].tobytes() == b[key].tobytes(), key
        else:
            assert a[key] == b[key], key


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input_changes_nothing_in_the_compiled_update(bad):
    Y = _reference(5)
    fast, oracle = _pair(Y)
    for amex in (fast, oracle):
        amex.update(Y[0], Y[-1])
    y = Y[1].copy()
    y[2] = bad
    with pytest.raises(InputError, match="non-finite y"):
        fast.update(y, Y[-1])
    assert _same(fast, oracle, fast.update(Y[1], Y[-1]), oracle.update(Y[1], Y[-1]))
