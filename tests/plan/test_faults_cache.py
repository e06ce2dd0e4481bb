"""Fault injection, the plan cache: damaged or mismatched files are replaced, never used."""

import logging

import numpy as np
import pytest

from amex.plan.cache import load_cached, plan_key, reference_plan, solve_reference
from amex.plan.reference import PlanConfig

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
