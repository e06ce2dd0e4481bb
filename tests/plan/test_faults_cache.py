"""Fault injection, the plan cache: damaged or mismatched files are replaced, never used."""

import logging

import numpy as np
import pytest

from amex.plan.cache import (
    END_TOLERANCE,
    end_step,
    load_cached,
    plan_key,
    plan_spec,
    reference_plan,
    solve_reference,
    store,
)
from amex.plan.reference import PlanConfig, ReferencePlan

GOAL = np.array([0.384, 0.229, 0.461])
AXIS = np.array([0.0, 0.0, -1.0])
CONFIG = PlanConfig(duration=0.5)  # 50 knots: solved in milliseconds


@pytest.fixture(scope="module")
def fresh(robot):
    return solve_reference(robot, CONFIG, GOAL, AXIS)


def _path(robot, directory):
    return directory / f"plan_{plan_key(robot, CONFIG, GOAL, AXIS)}.npz"


def _save(path, **arrays):
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def _damage(kind, path, plan):
    good = {"q": plan.q, "y": plan.y, "dt": plan.dt}
    if kind == "zero_bytes":
        path.write_bytes(b"")
    elif kind == "truncated":
        _save(path, **good)
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    elif kind == "garbled":
        _save(path, **good)
        data = bytearray(path.read_bytes())
        data[100:400] = np.random.default_rng(0).integers(0, 256, 300, dtype=np.uint8).tobytes()
        path.write_bytes(bytes(data))
    elif kind == "not_npz":
        path.write_text("hello")
    elif kind == "wrong_shape":
        _save(path, **{**good, "q": plan.q[:-5], "y": plan.y[:-5]})
    elif kind == "wrong_width":
        _save(path, **{**good, "y": plan.y[:, :3]})
    elif kind == "wrong_dt":
        _save(path, **{**good, "dt": 0.02})
    elif kind == "nan":
        y = plan.y.copy()
        y[7, 2] = np.nan
        _save(path, **{**good, "y": y})
    elif kind == "other_start":
        _save(path, **{**good, "q": plan.q + 0.1})
    elif kind == "missing_key":
        _save(path, q=plan.q, y=plan.y)
    elif kind == "a_directory":
        path.mkdir(parents=True)


KINDS = [
    "zero_bytes",
    "truncated",
    "garbled",
    "not_npz",
    "wrong_shape",
    "wrong_width",
    "wrong_dt",
    "nan",
    "other_start",
    "missing_key",
]


@pytest.mark.parametrize("kind", KINDS)
def test_a_damaged_or_mismatched_cache_file_is_solved_again_and_replaced(
    robot, fresh, tmp_path, kind
):
    path = _path(robot, tmp_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _damage(kind, path, fresh)
    assert load_cached(path, robot, CONFIG, GOAL, AXIS) is None
    plan = reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)
    np.testing.assert_array_equal(plan.q, fresh.q)
    np.testing.assert_array_equal(plan.y, fresh.y)
    again = load_cached(path, robot, CONFIG, GOAL, AXIS)  # the file was replaced by a valid one
    assert again is not None and np.array_equal(again.q, fresh.q)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left


def test_a_cache_path_that_is_a_directory_costs_a_warning_not_the_run(
    robot, fresh, tmp_path, caplog
):
    _damage("a_directory", _path(robot, tmp_path), fresh)
    with caplog.at_level(logging.WARNING, logger="amex.plan.cache"):
        plan = reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)
    np.testing.assert_array_equal(plan.q, fresh.q)
    assert "not written" in caplog.text


def test_a_cache_directory_that_is_a_file_costs_a_warning_not_the_run(
    robot, fresh, tmp_path, caplog, monkeypatch
):
    blocker = tmp_path / "cache"
    blocker.write_text("not a directory")
    monkeypatch.setenv("AMEX_CACHE_DIR", str(blocker))
    with caplog.at_level(logging.WARNING, logger="amex.plan.cache"):
        plan = reference_plan(robot, CONFIG, GOAL, AXIS)
    np.testing.assert_array_equal(plan.y, fresh.y)
    assert "not written" in caplog.text and "AMEX_CACHE_DIR" in caplog.text
    assert blocker.read_text() == "not a directory"


def test_a_read_only_cache_directory_costs_a_warning_not_the_run(
    robot, fresh, read_only_dir, caplog
):
    with caplog.at_level(logging.WARNING, logger="amex.plan.cache"):
        plan = reference_plan(robot, CONFIG, GOAL, AXIS, directory=read_only_dir / "plans")
    np.testing.assert_array_equal(plan.q, fresh.q)
    assert "not written" in caplog.text


def test_a_valid_cache_file_is_used_as_is(robot, fresh, tmp_path):
    path = _path(robot, tmp_path)
    reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)
    stamp = path.stat().st_mtime_ns
    plan = reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)
    assert path.stat().st_mtime_ns == stamp and np.array_equal(plan.q, fresh.q)


def _plan_of(robot, goal, config=CONFIG):
    return solve_reference(robot, config, goal, AXIS)


@pytest.mark.parametrize(
    ("other", "label"),
    [
        ("goal", "none"),  # an older file: no key inside
        ("goal", "its_own"),  # renamed or copied from another configuration's name
        ("goal", "forged"),  # carrying this configuration's key: the end check finds it out
        ("weights", "its_own"),  # same shape, start and goal, other final weights
    ],
)
def test_a_plan_of_another_configuration_under_this_name_is_never_used(
    robot, fresh, tmp_path, caplog, other, label
):
    if other == "goal":
        goal, config = GOAL + np.array([0.02, 0.0, 0.0]), CONFIG
    else:
        goal, config = GOAL, PlanConfig(duration=0.5, final_position=1e3)
    foreign = _plan_of(robot, goal, config)
    assert foreign.q.shape == fresh.q.shape and np.array_equal(foreign.q[0], fresh.q[0])
    path = _path(robot, tmp_path)
    if label == "none":
        _save(path, q=foreign.q, y=foreign.y, dt=foreign.dt)
    elif label == "its_own":
        store(path, foreign, plan_spec(robot, config, goal, AXIS))
    else:
        store(path, foreign, plan_spec(robot, CONFIG, GOAL, AXIS))
    with caplog.at_level(logging.WARNING, logger="amex.plan.cache"):
        plan = reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)
    np.testing.assert_array_equal(plan.q, fresh.q)
    reason = {
        "none": "unreadable",
        "its_own": "solved for another configuration",
        "forged": "its end is not where the solver puts it",
    }[label]
    assert f"{path} not used ({reason}" in caplog.text and "solved again" in caplog.text
    again = load_cached(path, robot, CONFIG, GOAL, AXIS)  # replaced by this configuration's
    assert again is not None and np.array_equal(again.q, fresh.q)


def test_an_edited_task_space_image_is_not_used(robot, fresh, tmp_path, caplog):
    path = _path(robot, tmp_path)
    y = fresh.y.copy()
    y[-1, 0] += 0.01  # the end moved without its joints
    store(path, ReferencePlan(q=fresh.q, y=y, dt=fresh.dt), plan_spec(robot, CONFIG, GOAL, AXIS))
    with caplog.at_level(logging.WARNING, logger="amex.plan.cache"):
        plan = reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)
    np.testing.assert_array_equal(plan.y, fresh.y)
    assert "not the kinematics of its joints" in caplog.text


@pytest.mark.parametrize(
    "config",
    [PlanConfig(), PlanConfig(duration=0.5), PlanConfig(final_position=10.0)],
    ids=["default", "short", "weak_final_weight"],
)
def test_a_solved_plan_passes_its_own_end_check_even_where_it_misses_the_goal(robot, config):
    plan = solve_reference(robot, config, GOAL, AXIS)
    position, axis = end_step(robot, config, plan.q, GOAL, AXIS)
    assert position < END_TOLERANCE / 2 and axis < END_TOLERANCE / 2
    moved = end_step(robot, config, plan.q, GOAL + np.array([0.0, 0.0, 5e-4]), AXIS)[0]
    assert moved > END_TOLERANCE  # a plan of a goal 0.5 mm away is found out


def test_a_plan_this_code_solved_and_checked_is_read_without_a_second_end_check(
    robot, fresh, tmp_path, monkeypatch
):
    import amex.plan.cache as cache

    reference_plan(robot, CONFIG, GOAL, AXIS, directory=tmp_path)  # solved, checked, stored
    path = _path(robot, tmp_path)
    checks = []
    real = cache._end_problem
    monkeypatch.setattr(cache, "_end_problem", lambda *a: checks.append(1) or real(*a))
    plan = load_cached(path, robot, CONFIG, GOAL, AXIS)
    assert plan is not None and np.array_equal(plan.q, fresh.q) and checks == []
    # the same file with one joint angle changed: its digest no longer fits, the check runs
    with np.load(path) as f:
        fields = {k: f[k] for k in f.files}
    fields["q"], fields["y"] = fields["q"].copy(), fields["y"].copy()
    fields["q"][-1, 0] += 1e-3
    fields["y"][-1] = robot.task_position(fields["q"][-1])  # its image still its kinematics
    _save(path, **fields)
    assert load_cached(path, robot, CONFIG, GOAL, AXIS) is None and checks == [1]
