"""Episode logs: the real foxglove-sdk writer, the mcap readers, and ``amex-log`` (no mocks)."""

import csv
import math
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from mcap.reader import make_reader

from amex.app.log_cli import main
from amex.core.errors import (
    EmptyLogError,
    LogExistsError,
    LogNotFoundError,
    NotMcapError,
    TruncatedLogError,
)
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log import EpisodeLogger, read_log, recover
from amex.log.writer import LinkTransforms
from amex.methods.dmp import DMPConfig

PER_STEP_TOPICS = ("/tf", "/joint_states", "/tcp", "/goal", "/command", "/method")


def _config(max_time=1.0):
    config = RunConfig(task=3, max_time=max_time)
    config.method = DMPConfig()
    return config


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    """One logged Task-3 DMP episode of 1 s: (config, context, result, path)."""
    config = _config()
    context = prepare(config)
    path = tmp_path_factory.mktemp("log") / "logs" / "episode_000.mcap"
    result = run_one(config, context, 0, path)
    return config, context, result, path


def _outer_steps(result, config):
    """Outer steps recorded: one per 10 inner steps before the inner step the episode ended at."""
    k_end = round(result.final_time * config.inner_hz)
    return math.ceil(k_end / config.loop.substeps)


def test_logged_episode_opens_with_the_indexed_reader_and_has_foxglove_schemas(logged):
    config, _, result, path = logged
    assert path.exists() and not path.with_name(path.name + ".part").exists()
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        schemas = {s.name for s in summary.schemas.values()}
        assert {"foxglove.FrameTransforms", "foxglove.SceneUpdate", "foxglove.JointStates"} <= (
            schemas
        )
        topic_of = {c.id: c.topic for c in summary.channels.values()}
        counts = {topic_of[cid]: n for cid, n in summary.statistics.channel_message_counts.items()}
        steps = _outer_steps(result, config)
        assert steps == 100
        for topic in PER_STEP_TOPICS:
            assert counts[topic] == steps, topic
        assert counts["/episode"] == 1
        names = [m.name for m in reader.iter_metadata()]
    assert names[:4] == ["episode", "scenario", "robot", "log"] and names[-1] == "outcome"


def test_the_configurations_compressions_are_the_writers():
    from amex.experiment.config import LOG_COMPRESSIONS
    from amex.log.writer import COMPRESSIONS, DEFAULT_COMPRESSION

    assert set(LOG_COMPRESSIONS) == set(COMPRESSIONS)
    assert LOG_COMPRESSIONS[0] == DEFAULT_COMPRESSION == RunConfig().log_compression


def test_each_compression_writes_the_same_messages_that_the_reader_reads_back(logged, tmp_path):
    config, context, result, path = logged
    with open(path, "rb") as f:
        default = [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages()]
    for compression, recorded in (("lz4", "lz4"), ("zstd", "zstd"), ("none", "")):
        config.log_compression = compression
        again = tmp_path / f"{compression}.mcap"
        try:
            assert run_one(config, context, 0, again).as_row().keys() == result.as_row().keys()
        finally:
            config.log_compression = "lz4"
        with open(again, "rb") as f:
            reader = make_reader(f)
            chunks = reader.get_summary().chunk_indexes
            messages = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages()]
        assert chunks and {chunk.compression for chunk in chunks} == {recorded}
        same = [m for m in messages if m[0] not in ("/episode",)]  # timing columns there
        assert same == [m for m in default if m[0] not in ("/episode",)]
        data = read_log(again)
        assert not data.damage and data.outcome["final_distance"] == result.final_distance
    with pytest.raises(ValueError, match="valid: lz4, zstd, none"):
        EpisodeLogger(
            tmp_path / "bad.mcap", context.robot, context.plan, None, {}, compression="gzip"
        )
    assert not list(tmp_path.glob("bad.mcap*"))


def test_reader_gives_the_episode_back(logged):
    config, context, result, path = logged
    data = read_log(path)
    assert not data.truncated
    assert data.metadata["episode"] == {"task": 3, "method": "dmp", "env": 0, "seed": 0}
    assert data.outcome["status"] == "finished"
    assert data.outcome["final_distance"] == result.final_distance
    assert data.duration == pytest.approx(result.final_time)  # /episode is at the end
    tcp = data.series("/tcp", "position")
    assert tcp.shape == (100, 3)
    assert np.allclose(tcp[0], context.plan.y[0, :3], atol=1e-6)
    q, qdd = data.joints("position"), data.joints("acceleration")
    assert q.shape == qdd.shape == (100, 7) and np.isfinite(qdd).all()
    assert np.allclose(q[0], context.robot.q0)
    tf = data.decoded("/tf")[0].data["transforms"]
    assert [(f["parent_frame_id"], f["child_frame_id"]) for f in tf][:2] == [
        ("world", "panda_link0"),
        ("panda_link0", "panda_link1"),
    ]
    samples = data.messages["/reference"][0].data["samples"]
    assert np.allclose([s["position"] + s["axis"] for s in samples], context.plan.y, atol=1e-6)
    assert np.allclose(data.reference_path(), context.plan.y[:, :3], atol=1e-6)
    assert np.allclose(data.times("/tcp"), np.arange(100) * 0.01)
    phase = data.series("/method", "phase")
    assert phase.shape == (100,) and np.all(np.diff(phase) < 0)


def test_link_transforms_compose_to_the_tcp_pose(robot):
    links = LinkTransforms(robot)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = robot.q0 + rng.uniform(-0.5, 0.5, robot.nv)
        poses = {"world": pin.SE3.Identity()}
        for parent, child, t, (x, y, z, w) in links.compute(q):
            local = pin.SE3(pin.Quaternion(w, x, y, z).matrix(), np.array(t))
            poses[child] = poses[parent] * local
        expected = robot.tcp_pose(q)
        assert np.allclose(poses["panda_hand_tcp"].homogeneous, expected.homogeneous, atol=1e-12)
    names = {c for _, c in links.links}
    assert {f"panda_link{i}" for i in range(9)} | {"panda_hand", "panda_hand_tcp"} <= names


def test_logger_never_overwrites_a_file_it_keeps_it_aside(logged, tmp_path, caplog):
    _, context, _, _ = logged
    from amex.sim.scenario import make_scenario

    scenario = make_scenario(_config().scene(), 3, 0, 0, context.plan.y[0, :3], 4.0)
    path = tmp_path / "episode_000.mcap"
    path.write_bytes(b"earlier log")
    (tmp_path / "episode_000.mcap.part").write_bytes(b"interrupted log")
    with caplog.at_level("WARNING"):
        EpisodeLogger(path, context.robot, context.plan, scenario, {}).close()
    assert (tmp_path / "episode_000.old1.mcap").read_bytes() == b"earlier log"
    assert (tmp_path / "episode_000.old1.mcap.part").read_bytes() == b"interrupted log"
    assert read_log(path).outcome["status"] == "incomplete"
    assert not (tmp_path / "episode_000.mcap.part").exists()
    assert "kept it as episode_000.old1.mcap" in caplog.text


_CHILD = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    from amex.experiment.config import RunConfig
    from amex.sim.episode import run_episode
    from amex.log import EpisodeLogger
    from amex.methods import get_method
    from amex.methods.dmp import DMPConfig
    from amex.experiment.runner import prepare
    from amex.sim.scenario import make_scenario

    config = RunConfig(task=3, max_time=10.0)
    config.method = DMPConfig()
    ctx = prepare(config)
    scenario = make_scenario(config.scene(), 3, 0, 0, ctx.plan.y[0, :3], ctx.plan.duration)
    method = get_method("dmp")(ctx.plan, config.method, 0.01, ctx.robot)
    logger = EpisodeLogger(Path(sys.argv[1]), ctx.robot, ctx.plan, scenario, {"task": 3})

    class Tee:
        n = 0

        def record(self, step):
            logger.record(step)
            self.n += 1
            if self.n == 150:  # 1.5 s of simulation logged: wait to be killed
                print("ready", flush=True)
                time.sleep(120)

        def finish(self, result):
            logger.finish(result)

    run_episode(ctx.robot, method, scenario, config.gains(), config.loop, Tee())
    logger.close()
    """
)


def _log_until_ready_then(sig, path):
    proc = subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout.readline().strip() == "ready"
        proc.send_signal(sig)
        return proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sigkilled_logger_leaves_a_file_whose_completed_chunks_are_recovered(tmp_path, capsys):
    path = tmp_path / "episode.mcap"
    part = tmp_path / "episode.mcap.part"
    assert _log_until_ready_then(signal.SIGKILL, path) == -signal.SIGKILL
    assert part.exists() and not path.exists()
    with open(part, "rb") as f, pytest.raises(Exception):  # noqa: B017 - the index is gone
        make_reader(f).get_summary()
    data = read_log(part)
    assert data.truncated and data.outcome is None
    assert data.metadata["episode"] == {"task": 3}
    n_tf = data.channels["/tf"].message_count
    assert 50 <= n_tf <= 150  # all but the last chunk (64 KiB, a few dozen steps)
    assert np.allclose(data.times("/tf"), np.arange(n_tf) * 0.01)

    out = tmp_path / "recovered.mcap"
    recovered = recover(part, out)
    assert recovered.message_count == data.message_count
    with open(out, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary.statistics.message_count == data.message_count
        assert sum(1 for _ in reader.iter_messages()) == data.message_count
    again = read_log(out)
    assert not again.truncated and again.metadata["recovery"]["truncated"] is True
    with pytest.raises(LogExistsError):
        recover(part, out)

    assert main(["info", str(part)]) == 0
    text = capsys.readouterr().out
    assert f"recovered {data.message_count} messages from a truncated file" in text


def test_sigterm_finishes_the_log_and_still_terminates(tmp_path):
    path = tmp_path / "episode.mcap"
    assert _log_until_ready_then(signal.SIGTERM, path) == -signal.SIGTERM
    assert path.exists() and not (tmp_path / "episode.mcap.part").exists()
    with open(path, "rb") as f:
        assert make_reader(f).get_summary() is not None
    data = read_log(path)
    assert not data.truncated
    assert data.outcome["status"] == "terminated" and data.outcome["signal"] == "SIGTERM"
    assert data.channels["/tf"].message_count == 150


def _bad_files(tmp_path, good):
    missing = tmp_path / "missing.mcap"
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    text = tmp_path / "notes.mcap"
    text.write_text("not a log\n")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(good.read_bytes()[:200])  # header and schemas, no complete chunk
    return {"missing": missing, "empty": empty, "not_mcap": text, "truncated": cut}


@pytest.mark.parametrize(
    ("case", "error", "needle"),
    [
        ("missing", LogNotFoundError, "not found"),
        ("empty", EmptyLogError, "empty"),
        ("not_mcap", NotMcapError, "not an MCAP file"),
        ("truncated", TruncatedLogError, "truncated"),
    ],
)
def test_bad_files_raise_clear_errors_and_the_cli_exits_2(
    logged, tmp_path, capsys, case, error, needle
):
    bad = _bad_files(tmp_path, logged[3])[case]
    with pytest.raises(error, match=needle):
        read_log(bad)
    for command in (["info"], ["plot"], ["export"], ["recover", "-o", str(tmp_path / "o.mcap")]):
        with pytest.raises(SystemExit) as exit_info:
            main([command[0], str(bad), *command[1:]])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("amex-log: error: ") and needle in err


@pytest.mark.parametrize("argv", [[], ["bogus"], ["info"], ["export", "x.mcap", "--format=xls"]])
def test_bad_command_lines_exit_2_with_one_line(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("amex-log: error: ")


def test_cli_subprocess_prints_one_line_and_no_traceback(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    proc = subprocess.run(
        [sys.executable, "-m", "amex.app.log_cli", "info", str(tmp_path / "nope.mcap")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("amex-log: error: log file not found")


def test_export_csv_writes_readable_tables(logged, tmp_path, capsys):
    _, _, _, path = logged
    out = tmp_path / "export"
    assert main(["export", str(path), "--format", "csv", "-o", str(out)]) == 0
    with open(out / "joints.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 100
    assert {"time", "q_0", "q_6", "qd_0", "qdd_6", "tau_3"} <= set(rows[0])
    assert float(rows[1]["time"]) == pytest.approx(0.01)
    with open(out / "reference.csv", newline="") as f:
        reference = list(csv.DictReader(f))
    assert len(reference) == 401 and float(reference[-1]["time"]) == pytest.approx(4.0)
    for name in ("tcp", "goal", "command", "method", "episode"):
        assert (out / f"{name}.csv").stat().st_size > 0
    assert (out / "metadata.json").exists()
    assert "wrote" in capsys.readouterr().out


def test_export_parquet_without_pyarrow_names_the_package(logged, tmp_path, capsys):
    pytest.importorskip("pandas")
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        pass
    else:
        pytest.skip("pyarrow is installed")
    with pytest.raises(SystemExit) as exit_info:
        main(["export", str(logged[3]), "--format", "parquet", "-o", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "pip install pyarrow" in capsys.readouterr().err


def test_plot_writes_a_png(logged, tmp_path):
    png = tmp_path / "episode.png"
    assert main(["plot", str(logged[3]), "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_layout_points_the_urdf_layer_at_the_logs_urdf(logged, tmp_path):
    import json

    out = tmp_path / "layout.json"
    assert main(["layout", str(logged[3]), "-o", str(out)]) == 0
    layout = json.loads(out.read_text())
    urdf = layout["configById"]["3D!amex"]["layers"]["robot-urdf"]
    assert urdf["layerId"] == "foxglove.Urdf" and Path(urdf["filePath"]).exists()
    out = tmp_path / "ur5_layout.json"
    assert main(["layout", "--robot", "ur5", "-o", str(out)]) == 0  # no log: a catalogue robot
    layout = json.loads(out.read_text())
    urdf = layout["configById"]["3D!amex"]["layers"]["robot-urdf"]
    assert urdf["filePath"].endswith("ur5_robot.urdf") and Path(urdf["filePath"]).exists()
    assert len(layout["configById"]["Plot!qdd"]["paths"]) == 6


@pytest.mark.parametrize("method", ["amex", "cr", "dmp"])
def test_a_fresh_methods_steps_kept_without_copies_give_the_same_log(method, tmp_path):
    """``fresh_steps``: the command and internals kept as given write the copies' messages."""
    from amex.app.compose import load_config
    from amex.experiment.runner import _scenario, run_setup_with, setup

    config = load_config(["task=4", f"method={method}", "max_time=1.2"])
    run = setup(config, prepare(config))
    logs = []
    for fresh in (False, True):
        path = tmp_path / f"{fresh}.mcap"
        scenario, context = _scenario(run, 0), run.context
        with EpisodeLogger(
            path, context.robot, context.plan, scenario, {"method": method}, fresh_steps=fresh
        ) as logger:
            run_setup_with(run, 0, logger)
        with open(path, "rb") as f:
            logs.append([(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(
                log_time_order=False)])  # fmt: skip
    timing = ("/episode", "/method") if method == "cr" else ("/episode",)  # CR's solve_time
    copied, fresh = ([m for m in log if m[0] not in timing] for log in logs)
    assert len(copied) > 700 and copied == fresh
    assert [m[:2] for m in logs[0]] == [m[:2] for m in logs[1]]
    internals = [
        [
            {k: v for k, v in m.data.items() if k != "solve_time"}
            for m in read_log(p).messages["/method"]
        ]
        for p in (tmp_path / "False.mcap", tmp_path / "True.mcap")
    ]
    assert len(internals[0]) > 100 and internals[0] == internals[1]
