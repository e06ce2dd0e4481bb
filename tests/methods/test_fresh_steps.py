"""Methods that say ``fresh_steps`` give new commands and internals at every step, never changed.

:attr:`amex.methods.base.Method.fresh_steps` lets the log keep a step's command and
``internals()`` without copying them (issue #29). Each built-in method says so; here each one
runs real episodes (a moving goal; a moving goal among moving obstacles) while a recorder keeps
every step's objects and copies of their values, and at the end every value must still be
what it was at its step: a new dict each step, arrays and lists unchanged, a lazy value's
inputs unchanged, the command's arrays unchanged.
"""

import copy

import numpy as np
import pytest

from amex.app.compose import load_config
from amex.core.lazy import Lazy, LazyRows
from amex.experiment.runner import prepare, run_setup_with, setup
from amex.methods import METHODS, ORIGINAL_METHODS
from amex.methods.amex import AMEX

FRESH = sorted(
    [(name, "ours") for name, cls in METHODS.items() if cls.fresh_steps]
    + [(name, "original") for name, cls in ORIGINAL_METHODS.items() if cls.fresh_steps]
)


def _copy(value):
    if isinstance(value, LazyRows) and value.source is not None:
        return ("lazy rows", value, np.array(value.source, copy=True))
    if isinstance(value, np.ndarray | list):
        return copy.deepcopy(value)
    return value


def _unchanged(value, kept):
    if isinstance(kept, tuple) and kept[:1] == ("lazy rows",):
        return value is kept[1] and np.array_equal(value.source, kept[2], equal_nan=True)
    if isinstance(value, np.ndarray):
        return value.shape == kept.shape and value.tobytes() == kept.tobytes()
    if isinstance(value, Lazy):
        return value is kept
    return value is kept or value == kept or (value != value and kept != kept)


class _Keeper:
    """Keeps every step's internals and command, and copies of their values."""

    def __init__(self):
        self.steps = []

    def record(self, step):
        raw = dict(dict.items(step.internals))  # lazy values as they are
        values = {key: _copy(value) for key, value in raw.items()}
        command = tuple(step.command)
        self.steps.append((step.internals, raw, values, command, [_copy(p) for p in command]))

    def finish(self, result):
        pass

    def problems(self):
        out = []
        dicts = [internals for internals, *_ in self.steps]
        if len({id(d) for d in dicts}) != len(dicts):
            out.append("a dict of internals() was given at two steps")
        for k, (internals, raw, values, command, parts) in enumerate(self.steps):
            for key, value in dict.items(internals):
                if value is not raw[key] or not _unchanged(value, values[key]):
                    out.append(f"step {k}: internals()[{key!r}] changed")
            for j, (part, kept) in enumerate(zip(command, parts, strict=True)):
                if not _unchanged(part, kept):
                    out.append(f"step {k}: command part {j} changed")
        return out


def _episodes(name, implementation, keeper, tasks=(1, 4)):
    for task in tasks:
        overrides = [f"task={task}", f"method={name}", f"implementation={implementation}"]
        config = load_config([*overrides, "max_time=1.5"])
        run_setup_with(setup(config, prepare(config)), 0, keeper)


@pytest.mark.parametrize(("name", "implementation"), FRESH)
def test_a_fresh_methods_steps_are_new_and_never_changed(name, implementation):
    keeper = _Keeper()
    _episodes(name, implementation, keeper)
    assert len(keeper.steps) > 100
    assert keeper.problems() == []


def test_every_built_in_method_says_its_steps_are_fresh():
    assert {name for name, _ in FRESH} == set(METHODS)
    assert len(FRESH) == len(METHODS) + len(ORIGINAL_METHODS)


class _Reusing(AMEX):
    """AMEX whose command and internals reuse their buffers (what fresh_steps rules out)."""

    name = "amex"

    def step(self, obs):
        command = super().step(obs)
        if not hasattr(self, "_buffers"):
            self._buffers = (command.y.copy(), command.yd.copy())
        self._buffers[0][:] = command.y
        self._buffers[1][:] = command.yd
        return type(command).task(*self._buffers)

    def internals(self):
        return {**super().internals(), "y_star": self._buffers[0]}


def test_the_check_finds_a_method_that_reuses_its_buffers(monkeypatch):
    import amex.methods as registry

    monkeypatch.setitem(registry.METHODS, "amex", _Reusing)
    keeper = _Keeper()
    _episodes("amex", "ours", keeper, tasks=(1,))
    problems = keeper.problems()
    assert any("command part 0 changed" in p for p in problems)
    assert any("internals()['y_star'] changed" in p for p in problems)
