"""amex-live without a browser: the live scene, the pacing recorder, the session and the CLI.

Real episodes in MuJoCo (the default suite; the browser test is tests/live/test_live_browser.py).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from amex.app.live.cli import check_host, main
from amex.app.live.session import LiveSession
from amex.core.errors import UsageError
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, setup
from amex.log import read_log
from amex.methods import METHODS
from amex.sim.episode import run_episode
from amex.sim.live import LiveScenario, TimedMethod
from amex.sim.pacing import EpisodeStopped, LiveRecorder
from amex.sim.perception import GoalSensor, PerceptionConfig, PredictionConfig
from amex.sim.scenario import make_scenario


@pytest.fixture(scope="module")
def episode():
    """Task 2 (a moving goal), AMEX: the setup, the base scene and a method factory."""
    config = RunConfig(task=2)
    config.method = METHODS["amex"].config_class()
    context = prepare(config)
    s = setup(config, context)
    plan = context.plan
    base = make_scenario(s.scene, 2, 0, 0, plan.y[0, :3], plan.duration)

    def method():
        return TimedMethod(s.method.from_plan(plan, s.params, s.outer_dt, context.robot))

    return context, s, base, method


def test_live_scene_follows_the_environment_until_a_hand_moves_the_goal(episode):
    _, _, base, _ = episode
    scene = LiveScenario(base)
    assert np.allclose(scene.goal_at(0.5), base.goal_at(0.5))  # Task 2's own motion
    assert np.any(scene.goal_velocity)  # the loop re-reads the goal every step
    scene.now = 1.0
    target = base.goal_at(1.0) + [0.0, 0.06, 0.0]
    scene.set_goal(target)
    assert scene.goal_moved_at == 1.0
    assert np.allclose(scene.goal_at(0.99), base.goal_at(0.99))  # the past stays as it was
    assert np.allclose(scene.goal_at(1.0), target) and np.allclose(scene.goal_at(9.0), target)
    snapshot = scene.snapshot()  # what a recording's metadata says: static where moved
    assert np.allclose(snapshot.goal_start, target) and not np.any(snapshot.goal_velocity)
    with pytest.raises(ValueError, match="3 finite numbers"):
        scene.set_goal([0.0, np.nan, 0.0])


def test_a_dragged_goal_reaches_the_method_through_perception_latency(episode):
    _, _, base, _ = episode
    scene = LiveScenario(base)
    sensor = GoalSensor(scene.goal_at, PerceptionConfig(latency=0.05), PredictionConfig(),
                        np.random.default_rng(0))  # fmt: skip
    scene.now = 2.0
    old = scene.goal_at(2.0).copy()
    scene.set_goal(old + [0.0, 0.0, 0.08])
    # 50 ms late, as perception.latency says: what the goal was (moving, Task 2) 50 ms ago
    assert np.allclose(sensor.measure(2.03), base.goal_at(1.98))
    assert np.allclose(sensor.measure(2.06), old + [0.0, 0.0, 0.08])


def test_recorder_paces_the_loop_to_the_wall_clock_and_the_speed_factor(episode):
    context, s, base, method = episode
    loop = dataclasses.replace(s.loop, max_time=0.6, stop_radius=-1.0)
    for speed in (1.0, 3.0):
        recorder = LiveRecorder(LiveScenario(base), speed)
        tic = time.perf_counter()
        result = run_episode(context.robot, method(), LiveScenario(base), s.gains, loop, recorder)
        wall = time.perf_counter() - tic
        assert result.final_time == pytest.approx(0.6)
        assert 0.6 / speed - 0.02 <= wall <= 0.6 / speed + 0.6  # never ahead of the clock
    assert recorder.stats.load < 1.0


def test_paused_loop_moves_only_by_single_steps_and_stop_ends_the_episode(episode):
    import threading

    context, s, base, method = episode
    scene = LiveScenario(base)
    recorder = LiveRecorder(scene, 1.0, paused=True)
    seen: list[float] = []
    recorder.on_step = lambda step, pace: seen.append(step.t)
    loop = dataclasses.replace(s.loop, max_time=30.0, stop_radius=-1.0)
    errors: list[BaseException] = []

    def run():
        try:
            run_episode(context.robot, method(), scene, s.gains, loop, recorder)
        except BaseException as e:  # noqa: BLE001 (the test reads it)
            errors.append(e)

    thread = threading.Thread(target=run)
    thread.start()
    time.sleep(1.0)
    assert len(seen) == 1  # the first outer step, then held
    recorder.step(3)
    time.sleep(0.5)
    assert len(seen) == 4 and seen[-1] == pytest.approx(0.03)
    recorder.stop()
    thread.join(timeout=10)
    assert not thread.is_alive() and isinstance(errors[0], EpisodeStopped)


def test_pause_reads_held_only_once_the_loop_rests_after_its_last_step(episode):
    """A pause asked mid-step: the step under way finishes, then on_hold; nothing moves after."""
    import threading

    context, s, base, method = episode
    events: list[tuple[str, float]] = []
    scene = LiveScenario(base)
    recorder = LiveRecorder(scene, 1.0, on_hold=lambda: events.append(("hold", scene.now)))
    recorder.on_step = lambda step, pace: events.append(("step", step.t))
    loop = dataclasses.replace(s.loop, max_time=30.0, stop_radius=-1.0)
    def run():
        with pytest.raises(EpisodeStopped):
            run_episode(context.robot, method(), scene, s.gains, loop, recorder)

    thread = threading.Thread(target=run)
    thread.start()
    try:
        for _ in range(5):  # pause, wait for the hold, check, run on: at random points of a step
            time.sleep(0.2)
            recorder.pause()
            end = time.monotonic() + 5
            while not recorder.held and time.monotonic() < end:
                time.sleep(0.001)
            assert recorder.held
            at_hold = list(events)
            time.sleep(0.2)
            assert events == at_hold  # held: no step after the hold
            assert at_hold[-1][0] == "hold" and at_hold[-2][0] == "step"
            assert at_hold[-1][1] == at_hold[-2][1]  # held at the last step's time
            recorder.resume()
    finally:
        recorder.stop()
        thread.join(timeout=10)
    assert not thread.is_alive() and not recorder.held


@pytest.mark.slow
def test_session_switches_between_every_registered_method_and_records_a_log(tmp_path):
    session = LiveSession(["task=3"], max_time=20.0, record_dir=tmp_path)
    session.start()
    try:
        for name in sorted(METHODS):  # plugins included
            episode = session.state.episode
            session.switch_method(name)
            end = time.monotonic() + 60
            while (session.state.episode == episode or session.state.t < 0.3) and (
                time.monotonic() < end
            ):
                time.sleep(0.05)
            state = session.state
            assert state.method == name and state.status == "running", (name, state.status)
            assert state.t >= 0.3 and len(state.obstacles) == 1
        session.start_recording()
        end = time.monotonic() + 30
        while not (session.state.recording and session.state.t > 0.5) and time.monotonic() < end:
            time.sleep(0.05)
        recording = session.state.recording
        session.stop_recording()
        end = time.monotonic() + 30
        while session.last_log is None and time.monotonic() < end:
            time.sleep(0.05)
    finally:
        session.close()
    data = read_log(session.last_log)
    assert str(session.last_log) == recording
    assert data.metadata["episode"]["live"] is True
    assert data.metadata["episode"]["method"] == sorted(METHODS)[-1]
    assert data.outcome["status"] == "stopped" and len(data.messages["/joint_states"]) >= 40


def test_only_loopback_unless_remote_is_allowed(capsys):
    check_host("127.0.0.1", False)
    check_host("localhost", False)
    check_host("::1", False)
    check_host("0.0.0.0", True)
    with pytest.raises(UsageError, match="--allow-remote"):
        check_host("0.0.0.0", False)
    with pytest.raises(SystemExit) as exit_info:
        main(["--host", "192.0.2.1"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "drive the simulation" in err


def test_bad_override_is_one_line_and_exit_2(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["method=nope", "--port", "0"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "method" in err
