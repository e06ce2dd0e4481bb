"""The log-cost benchmark (:mod:`amex.app.bench_log`): what it measures (no time asserted)."""

import numpy as np
import pytest
from mcap.reader import make_reader

from amex.app.bench_log import ReplayRecorder, log_overhead, main, sdk_floor
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one, run_setup_with, setup
from amex.log import read_log
from amex.log.writer import BATCH
from amex.methods import METHODS


def test_log_overhead_times_each_environment_plain_and_logged():
    result = log_overhead(3, "amex", range(2), ["max_time=0.2"], verbose=False)
    assert all(len(part) == 2 for part in result)
    assert np.all(result.plain_cpu > 0) and np.all(result.logged_cpu > 0)
    assert np.all(result.plain_wall > 0) and np.all(result.logged_wall > 0)
    assert np.all(result.floor_cpu > 0) and np.all(result.replay_cpu > 0)
    np.testing.assert_allclose(result.floor(), result.floor_cpu / result.plain_cpu)
    np.testing.assert_allclose(result.replay(), result.replay_cpu / result.plain_cpu - 1)
    np.testing.assert_allclose(result.overhead("wall"), result.logged_wall / result.plain_wall - 1)
    with pytest.raises(ValueError, match="valid: thread, wall"):
        result.overhead("process")


def test_main_prints_one_summary_line_per_task_and_method(capsys):
    main(["max_time=0.1", "--tasks", "1", "--methods", "dmp", "--episodes", "1", "--quiet"])
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith("Task 1, dmp (1 env): log=full overhead")


def test_the_floor_writes_the_same_log_again_with_the_sdk(tmp_path):
    config = RunConfig(task=1, max_time=0.3)
    config.method = METHODS["amex"].config_class()
    path = tmp_path / "episode.mcap"
    run_one(config, prepare(config), 0, path)
    assert sdk_floor(path, tmp_path / "again.mcap") > 0
    first, again = read_log(path), read_log(tmp_path / "again.mcap")
    assert again.message_count == first.message_count > 100
    assert again.outcome == first.outcome and not again.damage
    assert messages(tmp_path / "again.mcap") == messages(path)


def messages(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        return [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages()]


@pytest.mark.parametrize("batch", [None, 1])
def test_the_replaying_recorder_writes_the_logs_messages_in_the_episode(tmp_path, batch):
    config = RunConfig(task=3, max_time=1.5)  # more steps than a batch
    config.method = METHODS["amex"].config_class()
    run = setup(config, prepare(config))
    path = tmp_path / "episode.mcap"
    logged = run_one(config, prepare(config), 0, path)
    recorder = ReplayRecorder(path, tmp_path / "again.mcap", batch)
    logs = []
    record = recorder.record
    recorder.record = lambda step: logs.append(recorder._next) or record(step)
    replayed = run_setup_with(run, 0, recorder)
    same = [key for key in logged.as_row() if "compute" not in key]  # timing columns aside
    assert [replayed.as_row()[k] for k in same] == [logged.as_row()[k] for k in same]
    again = read_log(tmp_path / "again.mcap")
    assert again.outcome == read_log(path).outcome and not again.damage
    assert sorted(messages(tmp_path / "again.mcap")) == sorted(messages(path))
    # what was written before each step: at every step, or a batch (BATCH steps) at a time
    written = sorted(set(logs))
    assert len(logs) > BATCH and 0 < logs[-1] < len(messages(path))
    if batch == 1:
        assert len(written) == len(logs)
    else:
        assert written == [0, logs[BATCH]] and logs[BATCH - 1] == 0 < logs[BATCH]
    with pytest.raises(ValueError, match="valid: an integer >= 1"):
        ReplayRecorder(path, tmp_path / "x.mcap", 0)
