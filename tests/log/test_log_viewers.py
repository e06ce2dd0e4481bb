"""Logs for browser viewers: the JSON schemas' rule, the per-step protobuf channels, the served
robot, the server, the layout.

Real episodes of every built-in method are logged (0.5 s of Task 4, which has a moving obstacle);
the browser itself is exercised by ``tests/test_viewer_browser.py`` (``make test-viewer``).
"""

import json
import subprocess
import sys
import urllib.error
import urllib.parse
import urllib.request
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log import read_log
from amex.log.layout import build_layout
from amex.log.messages import viewer_schema_problems
from amex.log.serve import LogServer
from amex.log.urdf import viewer_urdf
from amex.methods import BUILTIN_METHODS, get_method
from amex.robot.meshes import resolve_mesh

AMEX_LOG = str(Path(sys.executable).parent / "amex-log")


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """One 0.5 s Task-4 episode per built-in method, logged: {method: path}."""
    out = tmp_path_factory.mktemp("logs")
    paths = {}
    for name in sorted(BUILTIN_METHODS):
        config = RunConfig(task=4, max_time=0.5)
        config.method = get_method(name).config_class()
        paths[name] = out / f"{name}.mcap"
        run_one(config, prepare(config), 0, paths[name])
    return paths


@pytest.fixture(scope="module")
def robot_logs(tmp_path_factory):
    """0.3 s of Task 1 with AMEX on the other catalogue arms: {robot: path}."""
    from amex.app.compose import load_config

    out = tmp_path_factory.mktemp("robots")
    paths = {}
    for robot in ("ur5", "chain7"):
        config = load_config([f"robot={robot}", "task=1", "method=amex", "max_time=0.3"])
        paths[robot] = out / f"{robot}.mcap"
        run_one(config, prepare(config), 0, paths[robot])
    return paths


def _json_schemas(path):
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    schemas = {s.id: s for s in summary.schemas.values()}
    for channel in summary.channels.values():
        if channel.message_encoding == "json":
            yield channel.topic, json.loads(schemas[channel.schema_id].data)


def _kind(value):
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, (int, float)):
        return "number"
    return {str: "string", list: "array", dict: "object"}[type(value)]


def _undeclared(value, schema, where):
    """Fields of ``value`` the schema does not declare, or declares as another kind."""
    problems = []
    for key, item in value.items():
        prop = schema["properties"].get(key)
        if prop is None:
            problems.append(f"{where}.{key} undeclared")
        elif item is not None and _kind(item) != prop["type"].replace("integer", "number"):
            problems.append(f"{where}.{key} is {_kind(item)}, declared {prop['type']}")
        elif isinstance(item, dict):
            problems += _undeclared(item, prop, f"{where}.{key}")
        elif isinstance(item, list) and prop["items"]["type"] == "object":
            for element in item[:3]:
                problems += _undeclared(element, prop["items"], f"{where}.{key}[]")
    return problems


@pytest.mark.parametrize("method", sorted(BUILTIN_METHODS))
def test_every_json_channel_follows_the_viewers_schema_rule_and_declares_every_field(logs, method):
    data = read_log(logs[method])
    schemas = dict(_json_schemas(logs[method]))
    assert {"/reference", "/episode"} <= set(schemas)
    for topic, schema in schemas.items():
        assert viewer_schema_problems(schema, topic) == []
        for message in data.messages[topic]:
            assert _undeclared(message.data, schema, topic) == []


@pytest.mark.parametrize("method", sorted(BUILTIN_METHODS))
def test_every_per_step_channel_is_amex_protobuf_read_back_field_by_field(logs, method):
    from mcap.reader import make_reader

    from amex.log.flat_proto import FlatDecoder

    data = read_log(logs[method])
    with open(logs[method], "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    for topic in ("/tcp", "/goal", "/command", "/method"):
        schema = topics[topic]
        assert schema.encoding == "protobuf" and schema.name.startswith("amex.")
        decoder = FlatDecoder(schema.data, schema.name)  # the schema parses, its fields are flat
        messages = data.messages[topic]
        assert messages and all(isinstance(m.data, dict) for m in messages)
        assert all(list(m.data) == list(messages[0].data) for m in messages)
        assert messages[0].data == decoder.decode(_first_message(logs[method], topic))
        assert all(round(m.data["t"] * 1e9) == m.log_time for m in messages)


def _first_message(path, topic):
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return next(m for _, c, m in make_reader(f).iter_messages(topics=[topic])).data


def test_viewer_rule_rejects_what_foxglove_rejects():
    old_reference = {
        "type": "object",
        "properties": {"dt": {"type": "number"}, "y": {"type": "array"}},
    }
    assert viewer_schema_problems(old_reference, "/reference") == [
        '/reference.y: an array needs scalar or object "items"'
    ]
    matrix = {"type": "array", "items": {"type": "array", "items": {"type": "number"}}}
    assert viewer_schema_problems({"type": "object", "properties": {"y": matrix}})
    assert viewer_schema_problems({"type": "object", "properties": {"a": {"type": "null"}}})
    assert viewer_schema_problems({"type": "object", "properties": {"a": {"type": ["number"]}}})
    assert viewer_schema_problems({"type": "object"}) == ['schema: an object needs "properties"']
    nested = {"type": "array", "items": {"type": "object", "properties": {"x": {"type": "x"}}}}
    assert viewer_schema_problems({"type": "object", "properties": {"p": nested}}) == [
        "schema.p[].x: unsupported type 'x'"
    ]


def test_served_urdf_keeps_no_package_urls_and_lists_every_mesh(logs):
    urdf_path = read_log(logs["amex"]).metadata["robot"]["urdf_path"]
    assert "package://" in Path(urdf_path).read_text()
    urdf = viewer_urdf(urdf_path, "http://127.0.0.1:1/robot/")
    assert "package://" not in urdf.text and urdf.replaced == ()
    meshes = [m.get("filename") for m in ET.fromstring(urdf.text.split("\n", 1)[1]).iter("mesh")]
    assert meshes and all(m.startswith("http://127.0.0.1:1/robot/meshes/") for m in meshes)
    assert {m.removeprefix("http://127.0.0.1:1/robot/") for m in meshes} == set(urdf.files)
    assert all(path.is_file() for path in urdf.files.values())


def test_missing_meshes_are_drawn_as_the_links_collision_shapes(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(
        '<robot name="arm"><link name="base"><visual><geometry>'
        '<mesh filename="package://nowhere/base.dae"/></geometry></visual>'
        '<collision><geometry><sphere radius="0.1"/></geometry></collision></link>'
        '<link name="tip"><visual><geometry><box size="1 1 1"/></geometry></visual></link>'
        "</robot>"
    )
    served = viewer_urdf(urdf, "http://h/")
    assert served.replaced == ("base",) and "nowhere" not in served.text
    assert served.text.count("<visual>") == 2 and '<sphere radius="0.1"' in served.text
    assert resolve_mesh("package://nowhere/base.dae", urdf) is None


def test_server_answers_byte_ranges_with_cors_and_the_private_network_preflight(logs):
    data = read_log(logs["dmp"])
    size = data.path.stat().st_size
    foxglove = {"Origin": "https://app.foxglove.dev"}
    with LogServer(data, port=0) as server:
        request = urllib.request.Request(
            server.urls.log, headers={"Range": "bytes=0-7", **foxglove}
        )
        with urllib.request.urlopen(request) as response:
            assert response.status == 206 and response.read() == b"\x89MCAP0\r\n"
            assert response.headers["Content-Range"] == f"bytes 0-7/{size}"
            assert response.headers["Access-Control-Allow-Origin"] == "https://app.foxglove.dev"
        tail = urllib.request.Request(server.urls.log, headers={"Range": "bytes=-8"})
        with urllib.request.urlopen(tail) as response:
            assert response.read() == data.path.read_bytes()[-8:]
        preflight = urllib.request.Request(
            server.urls.log,
            method="OPTIONS",
            headers={"Access-Control-Request-Private-Network": "true", **foxglove},
        )
        with urllib.request.urlopen(preflight) as response:
            assert response.headers["Access-Control-Allow-Private-Network"] == "true"
        with urllib.request.urlopen(server.urls.urdf) as response:
            assert b"<robot" in response.read()
        with pytest.raises(urllib.error.HTTPError, match="416"):
            urllib.request.urlopen(
                urllib.request.Request(server.urls.log, headers={"Range": f"bytes={size}-"})
            )
        with pytest.raises(urllib.error.HTTPError, match="404"):
            urllib.request.urlopen(server.urls.log.rsplit("/", 1)[0] + "/../etc/passwd")
    assert server.urls.foxglove.startswith("https://app.foxglove.dev/?ds=remote-file&ds.url=")


def test_layout_shows_the_scene_topics_that_have_messages_and_one_plot_line_per_joint(logs):
    for method, path in logs.items():
        data = read_log(path)
        layout = build_layout(data, urdf_url="http://h/robot/robot.urdf")
        scene = layout["configById"]["3D!amex"]
        with_messages = {
            t for t, c in data.channels.items() if t.startswith("/scene/") and c.message_count
        }
        assert set(scene["topics"]) == with_messages
        planners = {"cr", "mppi"}  # the methods whose internals() carry a plan
        assert ("/scene/plan" in scene["topics"]) == (method in planners)
        assert scene["layers"]["robot-urdf"]["url"] == "http://h/robot/robot.urdf"
        joints = data.metadata["robot"]["joint_names"]
        lines = layout["configById"]["Plot!qdd"]["paths"]
        assert [line["label"] for line in lines] == joints
        phase = layout["configById"]["Plot!phase"]["paths"]
        assert phase and all(p["value"].startswith("/method.") for p in phase)


def test_view_prints_the_urls_and_serves_until_stopped(logs):
    proc = subprocess.Popen(
        [AMEX_LOG, "view", str(logs["amex"]), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        first, web = proc.stdout.readline(), proc.stdout.readline()
        assert first.startswith("serving ") and "Ctrl-C" in first
        url = web.split()[-1]
        assert url.startswith("https://app.foxglove.dev/?ds=remote-file&ds.url=http%3A%2F%2F")
        log_url = urllib.parse.unquote(url.split("ds.url=")[1])
        with urllib.request.urlopen(log_url) as response:
            assert response.read(8) == b"\x89MCAP0\r\n"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


@pytest.mark.parametrize("robot", ["ur5", "chain7"])
def test_any_logged_robot_is_served_with_its_own_links_and_meshes(robot_logs, robot):
    data = read_log(robot_logs[robot])
    meta = data.metadata["robot"]
    assert meta["name"] == robot
    with LogServer(data, port=0) as server:
        with urllib.request.urlopen(server.urls.urdf) as response:
            text = response.read().decode()
        links = {link.get("name") for link in ET.fromstring(text.split("\n", 1)[1]).iter("link")}
        assert {child for _, child in meta["links"]} <= links  # /tf's frames are URDF links
        assert "package://" not in text
        for mesh in ET.fromstring(text.split("\n", 1)[1]).iter("mesh"):
            with urllib.request.urlopen(mesh.get("filename")) as response:
                assert response.status == 200 and response.read(4)
    lines = build_layout(data)["configById"]["Plot!qdd"]["paths"]
    assert [line["label"] for line in lines] == meta["joint_names"]


def test_view_of_a_log_whose_robot_is_not_here_is_one_line_and_exit_2(logs, tmp_path, capsys):
    from mcap.writer import Writer

    from amex.app.log_cli import main

    raw = read_log(logs["dmp"])._raw
    moved = tmp_path / "moved.mcap"
    with open(moved, "wb") as f:  # the same log, recorded on a machine with the URDF elsewhere
        writer = Writer(f)
        writer.start()
        schemas = {i: writer.register_schema(s.name, s.encoding, s.data)
                   for i, s in raw.schemas.items()}  # fmt: skip
        channels = {i: writer.register_channel(c.topic, c.message_encoding, schemas[c.schema_id])
                    for i, c in raw.channels.items()}  # fmt: skip
        for record in raw.metadata:
            values = dict(record.metadata)
            if record.name == "robot":
                values["urdf_path"] = json.dumps("/elsewhere/panda.urdf")
            writer.add_metadata(record.name, values)
        for m in raw.messages:
            writer.add_message(channels[m.channel_id], m.log_time, m.data, m.publish_time)
        writer.finish()
    with pytest.raises(SystemExit) as exit_info:
        main(["view", str(moved), "--port", "0"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.count("\n") == 1
    assert "/elsewhere/panda.urdf is not on this machine" in err
