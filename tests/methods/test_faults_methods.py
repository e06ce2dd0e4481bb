"""Fault injection, methods: NaN and infinity into every method's step and numpy API.

Parametrized over the registry, so a method added later (a plugin too) is tested the same way:
a non-finite observation is rejected where it enters (:class:`Observation`), a value changed
after that check makes the method raise or answer finitely, and either way the method is as
usable afterwards as if the bad step had never happened.
"""

import dataclasses

import numpy as np
import pytest

from amex.core.errors import AmexError, ConfigError, InputError
from amex.methods import AMEX, BUILTIN_METHODS, DMP, METHODS, DMPPhaseStop, Observation
from amex.plan.cache import reference_plan
from amex.plan.reference import PlanConfig, ReferencePlan

GOAL = np.array([0.384, 0.229, 0.461])
AXIS = np.array([0.0, 0.0, -1.0])
DT = 0.01
ARRAYS = ("q", "qd", "y", "yd", "goal", "obstacles", "obstacle_radii")


@pytest.fixture(scope="module")
def plan(robot):
    return reference_plan(robot, PlanConfig(), GOAL, AXIS)


def _obs(plan, robot, k: int) -> Observation:
    q = plan.q[min(k, len(plan.q) - 1)].copy()
    return Observation(
        t=k * DT,
        q=q,
        qd=np.zeros(robot.nv),
        y=robot.task_position(q),
        yd=np.zeros(6),
        goal=np.concatenate([GOAL + 0.02, AXIS]),
        obstacles=np.array([[0.5, 0.5, 0.9]]),
        obstacle_radii=np.array([0.02]),
    )


@pytest.mark.parametrize("name", [f.name for f in dataclasses.fields(Observation)])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_an_observation_with_a_non_finite_value_is_rejected_naming_it(plan, robot, name, bad):
    good = _obs(plan, robot, 3)
    value = getattr(good, name)
    if isinstance(value, np.ndarray):
        value = value.copy()
        value.flat[0] = bad
    else:
        value = bad
    with pytest.raises(InputError, match=f"non-finite {name}"):
        dataclasses.replace(good, **{name: value})


def _command(method, obs):
    return [None if part is None else part.copy() for part in method.step(obs)]


def _example_plugin():
    """The documented example plugin's class, from its file (installed or not)."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "examples" / "amex_servo" / "amex_servo.py"
    spec = importlib.util.spec_from_file_location("amex_servo_example", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module.Servo


# amex's own methods (not whatever else is installed) and the example plugin, which must meet
# the contract it documents
CONTRACT = {**{name: METHODS[name] for name in sorted(BUILTIN_METHODS)}, "servo": None}


@pytest.mark.parametrize("name", sorted(CONTRACT))
@pytest.mark.parametrize("field", ARRAYS)
def test_nan_into_a_step_never_poisons_the_method(plan, robot, name, field):
    cls = CONTRACT[name] or _example_plugin()
    clean = cls(plan, cls.config_class(), DT, robot)
    hit = cls(plan, cls.config_class(), DT, robot)
    for method in (clean, hit):
        method.reset(_obs(plan, robot, 0))
        _command(method, _obs(plan, robot, 0))
    bad = _obs(plan, robot, 1)
    getattr(bad, field).flat[0] = np.nan  # changed after the observation's own check
    try:
        answer = hit.step(bad)
    except AmexError:  # a clear error, and nothing changed: the next step is step 1 again
        start = 1
    else:  # the method does not read that field: the step counts, as for the clean twin
        for part in answer:
            assert part is None or np.isfinite(part).all(), f"{name} answered NaN to NaN {field}"
        _command(clean, _obs(plan, robot, 1))
        start = 2
    for k in range(start, start + 3):
        expected = _command(clean, _obs(plan, robot, k))
        got = _command(hit, _obs(plan, robot, k))
        for a, b in zip(expected, got, strict=True):
            if a is not None:
                np.testing.assert_array_equal(b, a)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_amex_update_rejects_non_finite_input_and_stays_usable(plan, bad):
    clean, hit = AMEX(plan, dt=DT), AMEX(plan, dt=DT)
    g = plan.y[-1] + 0.01
    for amex in (clean, hit):
        amex.update(plan.y[0], g)
    y = plan.y[1].copy()
    y[0] = bad
    with pytest.raises(InputError, match="non-finite y"):
        hit.update(y, g)
    with pytest.raises(InputError, match="non-finite g"):
        hit.update(plan.y[1], np.full(6, bad))
    for k in range(1, 30):
        a, b = clean.update(plan.y[k], g), hit.update(plan.y[k], g)
        assert a.s == b.s and np.array_equal(a.y_star, b.y_star)


@pytest.mark.parametrize("cls", [DMP, DMPPhaseStop])
def test_dmp_update_rejects_non_finite_input_and_stays_usable(plan, cls):
    clean, hit = cls(plan, dt=DT), cls(plan, dt=DT)
    g = plan.y[-1] + 0.01
    for dmp in (clean, hit):
        dmp.update(g, DT)
    with pytest.raises(InputError, match="non-finite goal"):
        hit.update(np.full(6, np.nan), DT)
    for dt in (np.nan, np.inf, 0.0):
        with pytest.raises(ConfigError, match="dt"):
            hit.update(g, dt)
    if cls is DMPPhaseStop:
        with pytest.raises(InputError, match="non-finite y"):
            hit.update(g, DT, y=np.full(6, np.nan))
    with pytest.raises(InputError, match="non-finite y0"):
        hit.reset_state(np.full(6, np.inf))
    for _ in range(30):
        a, b = clean.update(g, DT), hit.update(g, DT)
        assert a.x == b.x and np.array_equal(a.y_star, b.y_star)


def test_amex_refuses_a_reference_that_does_not_move(plan):
    still = ReferencePlan(q=plan.q, y=np.repeat(plan.y[:1], len(plan.y), axis=0), dt=plan.dt)
    with pytest.raises(ConfigError, match="must move"):
        AMEX(still, dt=DT)


def test_a_prechecked_observation_equals_a_checked_one(plan, robot):
    good = _obs(plan, robot, 3)
    values = [getattr(good, f.name) for f in dataclasses.fields(Observation)]
    fast = Observation.prechecked(*values)
    assert type(fast) is Observation and fast == good or all(
        getattr(fast, f.name) is getattr(good, f.name) for f in dataclasses.fields(Observation)
    )
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.t = 1.0  # type: ignore[misc]
