"""Bad input is one line naming the bad value and the valid choices (the second audit's cases)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from amex.app.checks import validate_command_line
from amex.app.log_cli import main as amex_log
from amex.core.errors import UsageError

RUN = [sys.executable, "-c", "from amex.app.cli import run_main; run_main()"]


def _refused(argv):
    with pytest.raises(UsageError) as info:
        validate_command_line([*argv, "episodes=1"] if "episodes" not in str(argv) else argv)
    return str(info.value)


def test_malformed_yaml_names_its_file_and_line(tmp_path):
    (tmp_path / "experiment").mkdir()
    (tmp_path / "experiment" / "broken.yaml").write_text("# @package _global_\ntask: [1,\n")
    message = _refused(["--config-dir", str(tmp_path), "experiment=broken"])
    assert message.startswith(f"invalid YAML in {tmp_path / 'experiment' / 'broken.yaml'}, line 3")


def test_a_huge_scale_is_blamed_on_the_scale():
    message = _refused(["scenario.scale=1e9"])
    assert message.startswith("invalid scenario.scale=1e+09") and "scenario.scale <= 1" in message


@pytest.mark.parametrize(
    ("key", "values", "valid"),
    [
        ("episodes", ["0", "-1", "1000000000"], "an integer >= 1 and <= 1000000"),
        ("max_time", ["0", "-1"], "a finite number > 0"),
        ("outer_hz", ["0", "-5"], "a finite number > 0"),
        ("shards", ["0", "-2"], "an integer >= 1"),
    ],
)
def test_every_bad_value_of_a_field_gets_the_same_valid_range(key, values, valid):
    for value in values:
        assert _refused([f"{key}={value}"]).endswith(f"valid: {valid}")


def test_an_episode_too_long_to_keep_in_memory_is_refused_before_a_directory_exists(tmp_path):
    message = _refused(["max_time=1e9", f"hydra.run.dir={tmp_path / 'run'}"])
    assert "max_time x inner_hz <= 2,000,000" in message and not (tmp_path / "run").exists()


def test_every_robot_the_urdf_option_lists_can_be_chosen():
    validate_command_line(["robot=ur10", "episodes=1"])  # listed as a catalogue robot: runs


def test_the_experiment_choices_include_nested_ones():
    message = _refused(["experiment=nope"])
    assert "ablation/1_harness" in message and "original" in message


@pytest.mark.parametrize("kind", ["device", "fifo", "directory"])
def test_a_robot_description_that_is_no_regular_file_is_refused(tmp_path, kind):
    path = {"device": Path("/dev/zero"), "directory": tmp_path}.get(kind, tmp_path / "arm.urdf")
    if kind == "fifo":
        os.mkfifo(path)
    argv = ["robot=urdf", f"robot.urdf={path}", "robot.joints=[a]", "robot.tcp_frame=t",
            "robot.q0=[0]"]  # fmt: skip
    assert _refused(argv).endswith("valid: a regular file")


def test_versions_and_shell_completion_are_amexs():
    from amex import __version__

    run = subprocess.run([*RUN, "--version"], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == f"amex-run {__version__}"
    log = subprocess.run(
        [sys.executable, "-m", "amex.app.log_cli", "--version"], capture_output=True, text=True
    )
    assert log.returncode == 0 and log.stdout.strip() == f"amex-log {__version__}"
    completion = subprocess.run([*RUN, "-sc", "install=bash"], capture_output=True, text=True)
    assert completion.returncode == 0 and "complete" in completion.stdout


def test_a_glob_sweep_over_a_config_group_expands():
    from amex.app.checks import command_line_jobs

    jobs, _ = command_line_jobs(["method=glob(dmp*)", "task=0"], multirun=True)
    assert sorted(job[0] for job in jobs) == ["method=dmp", "method=dmp_avoid", "method=dmp_ps"]


@pytest.mark.parametrize(
    ("option", "value", "valid"),
    [("--fps", "1e7", "1..240"), ("--size", "20000x20000", "64..4096"), ("--speed", "0", "0.01")],
)
def test_video_options_beyond_any_screen_are_refused(tmp_path, capsys, option, value, valid):
    log = tmp_path / "episode.mcap"
    log.write_bytes(b"")
    with pytest.raises(SystemExit) as exit_info:
        amex_log(["video", str(log), option, value])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and len(err.strip().splitlines()) == 1 and valid in err


@pytest.mark.slow
def test_in_a_log_file_progress_comes_as_whole_lines(tmp_path):
    done = subprocess.run(
        [*RUN, "-m", "task=0", "method=track,amex", "episodes=2", "max_time=0.2",
         f"hydra.sweep.dir={tmp_path / 'sweep'}"],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "\r" not in done.stderr  # no bar redrawn in place: every line stands alone
    lines = done.stderr.splitlines()
    assert any(line.startswith("task0_track_seed0: success ") for line in lines)
    assert any(line.startswith("sweep sweep: 4/4 episodes (100 %)") for line in lines)
