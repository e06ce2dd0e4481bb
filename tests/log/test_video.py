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


def _panel_frame(log, geometry, width=320, height=240, zoom=1.0):
    """One rendered panel (RGB, top row first) and the panel, at the episode's end."""
    import mujoco

    from amex.log.reader import read_log
    from amex.log.render import gl_context
    from amex.log.video import FRAME_MARGIN, _Panel, track_of

    track = track_of(read_log(log))
    gl = gl_context(width, height)
    try:
        panel = _Panel(track, width, height, geometry)
        aim_camera(panel.camera, panel.look_points(), track.scenario.goal_start - track.tcp[0],
                   margin=FRAME_MARGIN)  # fmt: skip
        panel.camera.distance *= zoom
        context = mujoco.MjrContext(panel.model, mujoco.mjtFontScale.mjFONTSCALE_150)
        try:
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, context)
            viewport = mujoco.MjrRect(0, 0, width, height)
            panel.draw(context, track.end + 1.0, viewport)
            rgb = np.empty((height, width, 3), dtype=np.uint8)
            mujoco.mjr_readPixels(rgb, None, viewport, context)
        finally:
            context.free()
    finally:
        gl.free()
    return np.flipud(rgb), panel


def test_video_draws_the_robots_meshes_unless_capsules_are_asked_for(logs, tmp_path, capsys):
    import mujoco

    meshes, panel = _panel_frame(logs["amex"], "visual")
    capsules, capsule_panel = _panel_frame(logs["amex"], "collision")
    drawn = [panel.scene.geoms[i] for i in range(panel.scene.ngeom)]
    assert sum(int(g.type) == mujoco.mjtGeom.mjGEOM_MESH for g in drawn) >= 10  # the Panda's links
    # the Panda's collision model is cylinders (with spheres at their ends): hidden by default
    assert not any(int(g.type) == mujoco.mjtGeom.mjGEOM_CYLINDER for g in drawn)
    kinds = [int(capsule_panel.scene.geoms[i].type) for i in range(capsule_panel.scene.ngeom)]
    assert mujoco.mjtGeom.mjGEOM_CYLINDER in kinds and mujoco.mjtGeom.mjGEOM_MESH not in kinds
    assert not np.array_equal(meshes, capsules)
    out = tmp_path / "capsules.mp4"
    assert main(["video", str(logs["amex"]), "-o", str(out), "--fps", "5", "--size", "160x120",
                 "--capsules"]) == 0  # fmt: skip
    assert out.exists()


def test_video_frames_the_whole_arm_and_keeps_the_caption_off_it(logs):
    from amex.log.render import frame_points
    from amex.log.video import BAND, BAND_RGB

    width, height = 320, 240
    rgb, panel = _panel_frame(logs["dmp"], "visual", width, height)
    closer, _ = _panel_frame(logs["dmp"], "visual", width, height, zoom=0.5)
    band = min(BAND, height // 6)
    # the scene draws nothing into the caption's band above it nor the outcome's below it:
    # another camera changes the scene's pixels, not theirs, and they hold their text
    assert not np.array_equal(rgb[band:-band], closer[band:-band])
    for rows in (slice(0, band), slice(height - band, height)):
        assert np.array_equal(rgb[rows], closer[rows])
        background = np.all(np.abs(rgb[rows].astype(float) - np.array(BAND_RGB) * 255) < 3, -1)
        assert 1.0 - background.mean() > 0.05  # the text (and its box) is there
    # every body of the arm, at every logged configuration, projects into the scene's viewport
    points = frame_points(panel.model, panel.addresses, panel.track.q, 5)
    cam = panel.camera
    az, el = np.radians(cam.azimuth), np.radians(cam.elevation)
    forward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    eye = np.asarray(cam.lookat) - cam.distance * forward
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = points - eye
    depth = rel @ forward
    half_h = np.tan(np.radians(panel.model.vis.global_.fovy) / 2)
    aspect = width / (height - 2 * band)
    x = (rel @ right) / depth / (half_h * aspect)
    y = (rel @ up) / depth / half_h
    assert np.all(depth > 0) and np.all(np.abs(x) < 0.95) and np.all(np.abs(y) < 0.95)
