"""The Python API: the example of the docs runs, and the API checks its input like the CLI."""

import subprocess
import sys
from pathlib import Path

import pytest

import amex
from amex.core.errors import ConfigError, UsageError

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "python_api.py"


def test_the_documented_example_runs_from_another_directory(tmp_path):
    done = subprocess.run(
        [sys.executable, str(EXAMPLE), str(tmp_path / "out")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out" / "logs" / "episode_000.mcap").is_file()
    rows = amex.read_runs(tmp_path / "out")
    assert sorted(rows["method"].unique()) == ["amex", "dmp"] and len(rows) == 8
    assert set(rows["env"]) == {0, 1, 2, 3}


def test_compose_names_a_bad_value_as_the_command_line_does():
    with pytest.raises(ConfigError, match=r"invalid task=9; valid: 0, 1, 2, 3, 4"):
        amex.compose(task=9)
    with pytest.raises(UsageError, match=r"invalid method='nope'; valid: amex, "):
        amex.compose(method="nope")
    with pytest.raises(UsageError, match="unknown config key"):
        amex.compose(values={"method.bogus": 1})


def test_compose_takes_a_users_config_directory(tmp_path):
    (tmp_path / "experiment").mkdir()
    (tmp_path / "experiment" / "mine.yaml").write_text("# @package _global_\ntask: 2\nseed: 5\n")
    config = amex.compose("experiment=mine", config_dirs=[tmp_path], episodes=3)
    assert (config.task, config.seed, config.episodes) == (2, 5, 3)
    with pytest.raises(UsageError, match="invalid experiment='mine'"):
        amex.compose("experiment=mine")  # the directory is this call's, not the process's
