import numpy as np
import pytest

from amex.core.errors import ConfigError
from amex.experiment.config import RunConfig
from amex.robot.ik import solve_ik
from amex.sim.scenario import ScenarioConfig, goal_grid, make_scenario

START = np.array([0.307, 0.0, 0.487])


def _scene(config=None):
    """The scene in scene units, converted as a run converts it (the experiment layer)."""
    return RunConfig(scenario=config or ScenarioConfig()).scene()


def _make(task, env, seed=0, config=None):
    return make_scenario(_scene(config), task, seed, env, START, 4.0)


def test_task0_is_the_reference_scene():
    s = _make(0, 5)
    assert np.allclose(s.goal_at(0.0), [0.384, 0.229, 0.461])
    assert np.allclose(s.goal_at(7.0), s.goal_at(0.0))
    assert s.n_obstacles == 0


def test_grids_have_the_original_sizes_scaled():
    config = _scene()
    box = goal_grid(config, 1)
    plane = goal_grid(config, 3)
    assert box.shape == (150, 3) and plane.shape == (150, 3)
    assert np.allclose(np.ptp(box, axis=0), [0.14, 0.16, 0.36])
    assert np.allclose(plane[:, 0], 0.384 + 0.07)
    assert np.allclose(box.mean(axis=0), [0.384, 0.229, 0.461])


def test_environments_are_deterministic_and_differ_by_index():
    a, b = _make(2, 3, seed=7), _make(2, 3, seed=7)
    assert np.array_equal(a.goal_velocity, b.goal_velocity)
    assert not np.array_equal(a.goal_velocity, _make(2, 4, seed=7).goal_velocity)
    assert not np.array_equal(a.goal_velocity, _make(2, 3, seed=8).goal_velocity)


def test_task1_visits_every_grid_goal_once_in_150_environments():
    goals = np.array([_make(1, i).goal_start for i in range(150)])
    assert len(np.unique(goals.round(9), axis=0)) == 150


def test_goal_moves_only_during_the_window_and_obstacle_sits_at_the_midpoint():
    s = _make(3, 11)
    assert s.goal_stop_time == pytest.approx(2.8)
    assert np.allclose(s.goal_at(2.8), s.goal_at(9.0))
    assert not np.allclose(s.goal_at(1.0), s.goal_at(0.0))
    assert np.allclose(s.obstacle_start[0], (START + s.goal_start) / 2)
    assert s.obstacle_radii[0] == pytest.approx(0.02)
    assert np.allclose(s.obstacles_at(5.0), s.obstacles_at(0.0))
    moving = _make(4, 11)
    assert not np.allclose(moving.obstacles_at(5.0), moving.obstacles_at(0.0))


def test_speeds_scale_with_the_scene():
    v = np.array([_make(2, i).goal_velocity for i in range(300)])
    assert v.std() == pytest.approx(0.1 * 0.2, rel=0.15)


def test_every_grid_goal_is_reachable_top_down(robot):
    config = _scene()
    for task in (1, 3):
        for goal in goal_grid(config, task):
            res = solve_ik(robot, goal, np.array([0.0, 0.0, -1.0]))
            assert res.position_error < 1e-4 and res.axis_error < 1e-4, (task, goal)


def test_bad_task_is_rejected_with_the_choices():
    with pytest.raises(ConfigError, match=r"invalid task=9; valid: 0, 1, 2, 3, 4"):
        _make(9, 0)
