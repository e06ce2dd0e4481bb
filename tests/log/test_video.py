"""``amex-log video``: real MuJoCo offscreen rendering (EGL/OSMesa), imageio-ffmpeg's ffmpeg."""

import imageio_ffmpeg
import numpy as np
import pytest

from amex.app.log_cli import main
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log.render import aim_camera
from amex.log.video import render_video
from amex.methods import get_method


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """0.6 s of Task-4 environment 0 (moving obstacle) with AMEX and DMP: {method: path}."""
    out = tmp_path_factory.mktemp("video")
    paths = {}
    for name in ("amex", "dmp"):
        config = RunConfig(task=4, max_time=0.6)
        config.method = get_method(name).config_class()
        paths[name] = out / f"{name}.mcap"
        run_one(config, prepare(config), 0, paths[name])
    return paths


def _frames(path):
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(meta["size"][1], meta["size"][0], 3)
              for f in reader]  # fmt: skip
    return meta, frames


def test_video_has_a_frame_per_step_of_film_time_and_the_arm_moves(logs, tmp_path):
    out = tmp_path / "amex.mp4"
    info = render_video([logs["amex"]], out, fps=10, width=160, height=120)
    meta, frames = _frames(out)
    assert meta["size"] == (160, 120) and info.frames == len(frames)
    assert len(frames) == 7 + 10  # 0.0 .. 0.6 s at 10 frames/s, then a second on the last frame
    assert not np.array_equal(frames[0], frames[6])  # the arm and its path moved
    assert np.array_equal(frames[-1], frames[-2])  # the hold at the end
    assert frames[0].std() > 10  # not a blank image


def test_side_by_side_puts_each_method_in_its_own_panel(logs, tmp_path, capsys):
    out = tmp_path / "both.mp4"
    argv = ["video", str(logs["amex"]), str(logs["dmp"]), "-o", str(out), "--fps", "5",
            "--size", "160x120"]  # fmt: skip
    assert main(argv) == 0
    assert "320x120" in capsys.readouterr().out
    _, frames = _frames(out)
    left, right = frames[3][:, :160], frames[3][:, 160:]
    assert not np.array_equal(left, right)


def test_bad_video_options_exit_2_with_one_line(logs, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["video", str(logs["amex"]), "--size", "big", "-o", str(tmp_path / "x.mp4")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--size" in err


def test_camera_looks_across_the_motion_from_the_side_away_from_the_base():
    import mujoco

    camera = mujoco.MjvCamera()
    points = np.array([[0.4, -0.1, 0.4], [0.4, 0.3, 0.5]])
    aim_camera(camera, points, motion=np.array([0.0, 0.4, 0.0]))
    forward = np.array([np.cos(np.radians(camera.azimuth)), np.sin(np.radians(camera.azimuth))])
    assert forward @ np.array([0.0, 1.0]) == pytest.approx(0.0, abs=1e-9)  # across the motion
    assert forward[0] < 0  # the camera stands at +x, beyond the scene, looking at the robot
    assert np.allclose(camera.lookat, [0.4, 0.1, 0.45])
