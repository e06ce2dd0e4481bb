"""``amex-log view`` serves the log, its robot and meshes, nothing else, and only to its viewers.

One test per attack of issue #23: a real server on port 0, real HTTP requests (http.client, raw
sockets for malformed requests and idle connections), real URDFs in ``tmp_path`` naming files
outside the robot's package, FIFOs and devices, foreign origins and Host names, absurd ranges,
a log deleted or changed while served. The home directory is a folder of ``tmp_path`` holding a
fake ``.ssh/id_rsa``; ``/etc/passwd`` is the real one.
"""

import http.client
import json
import os
import selectors
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.writer import Writer

from amex.core.errors import LogError
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.log import read_log
from amex.log.serve import IDLE_TIMEOUT, MAX_CONNECTIONS, LogServer
from amex.methods import get_method

AMEX_LOG = str(Path(sys.executable).parent / "amex-log")
SECRET = b"-----BEGIN OPENSSH PRIVATE KEY----- not a real key\n"
MESH = b"solid base\nendsolid base\n"
EVIL = "https://evil.example"
LIMITED = [sys.executable, "-c", "import os, resource, sys; "
           "resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30)); "
           "os.execv(sys.argv[1], sys.argv[1:])"]  # fmt: skip


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    """A real 0.3 s episode log (DMP, Task 1)."""
    config = RunConfig(task=1, max_time=0.3)
    config.method = get_method("dmp").config_class()
    path = tmp_path_factory.mktemp("episode") / "episode.mcap"
    run_one(config, prepare(config), 0, path)
    return path


@pytest.fixture
def home(tmp_path, monkeypatch):
    """A home directory with a private key and a private mesh in it."""
    home = tmp_path / "home"
    (home / ".ssh").mkdir(parents=True)
    (home / ".ssh" / "id_rsa").write_bytes(SECRET)
    (home / "Documents").mkdir()
    (home / "Documents" / "secret.stl").write_bytes(SECRET)
    monkeypatch.setenv("HOME", str(home))
    return home


@pytest.fixture
def package(tmp_path):
    """A robot package: ``ws/arm_description/{package.xml, urdf/, meshes/base.stl}``."""
    package = tmp_path / "ws" / "arm_description"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    (package / "package.xml").write_text("<package><name>arm_description</name></package>")
    (package / "meshes" / "base.stl").write_bytes(MESH)
    return package


def write_urdf(package, *meshes):
    """``urdf/arm.urdf`` in ``package``: link ``base`` with the good mesh, a link per mesh."""
    links = "".join(
        f'<link name="l{i}"><visual><geometry><mesh filename="{m}"/></geometry></visual></link>'
        for i, m in enumerate(meshes)
    )
    urdf = package / "urdf" / "arm.urdf"
    urdf.write_text(
        '<robot name="arm"><link name="base"><visual><geometry>'
        '<mesh filename="package://arm_description/meshes/base.stl"/></geometry></visual>'
        f"</link>{links}</robot>"
    )
    return urdf


def relog(source, target, **robot):
    """``source`` rewritten to ``target`` with its ``robot`` metadata values replaced."""
    raw = read_log(source)._raw
    with open(target, "wb") as f:
        writer = Writer(f)
        writer.start()
        schemas = {i: writer.register_schema(s.name, s.encoding, s.data)
                   for i, s in raw.schemas.items()}  # fmt: skip
        channels = {i: writer.register_channel(c.topic, c.message_encoding, schemas[c.schema_id])
                    for i, c in raw.channels.items()}  # fmt: skip
        for record in raw.metadata:
            values = dict(record.metadata)
            if record.name == "robot":
                values.update({k: json.dumps(str(v) if isinstance(v, Path) else v)
                               for k, v in robot.items()})  # fmt: skip
            writer.add_metadata(record.name, values)
        for m in raw.messages:
            writer.add_message(channels[m.channel_id], m.log_time, m.data, m.publish_time)
        writer.finish()
    return target


def serve(episode, tmp_path, urdf, package_dirs=()):
    """A server (not started) of the episode with the robot description ``urdf``."""
    log = relog(
        episode, tmp_path / "view.mcap", urdf_path=str(urdf), package_dirs=list(package_dirs)
    )
    return LogServer(read_log(log), port=0)


def request(server, path, headers=None, method="GET", host=None):
    """``(status, headers, body)`` of one request; ``host`` replaces the Host header."""
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
    try:
        conn.putrequest(method, path, skip_host=host is not None, skip_accept_encoding=True)
        if host is not None:
            conn.putheader("Host", host)
        for key, value in (headers or {}).items():
            conn.putheader(key, value)
        conn.endheaders()
        response = conn.getresponse()
        return response.status, response.headers, response.read()
    finally:
        conn.close()


def mesh_paths(server):
    """The URL paths of the meshes the served URDF names."""
    status, _, urdf = request(server, "/robot/robot.urdf")
    assert status == 200
    urls = [u.split('"')[0] for u in urdf.decode().split('filename="')[1:]]
    return [u.split(f":{server.port}", 1)[1] for u in urls]


def assert_serves_only_the_package_mesh(server, *names):
    """The URDF names only the package's mesh; no URL it or a guess names serves a secret."""
    paths = mesh_paths(server)
    assert [p.rsplit("/", 1)[1] for p in paths] == ["base.stl"]
    assert request(server, paths[0])[2] == MESH
    for i in range(len(names) + 2):
        for name in names:
            status, _, body = request(server, f"/robot/meshes/{i}/{name}")
            assert status == 404 and SECRET not in body and b"root:" not in body


def test_mesh_at_an_absolute_path_outside_the_package_is_not_served(
    episode, tmp_path, home, package
):
    urdf = write_urdf(package, "/etc/passwd", str(home / ".ssh" / "id_rsa"))
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "passwd", "id_rsa")
        assert server.urdf.replaced == ("l0", "l1") and len(server.urdf.refused) == 2


def test_file_url_mesh_outside_the_package_is_not_served(episode, tmp_path, home, package):
    urdf = write_urdf(package, "file:///etc/passwd", f"file://{home}/.ssh/id_rsa")
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "passwd", "id_rsa")


def test_relative_mesh_climbing_out_of_the_package_is_not_served(episode, tmp_path, home, package):
    up = "../" * 40
    urdf = write_urdf(package, up + "etc/passwd", "../../../home/.ssh/id_rsa")
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "passwd", "id_rsa")


def test_package_url_climbing_out_of_its_package_is_not_served(episode, tmp_path, home, package):
    up = "../" * 40
    urdf = write_urdf(
        package,
        f"package://..{'/..' * 40}/etc/passwd",
        f"package://arm_description/{up}etc/passwd",
        "package://arm_description/../../home/.ssh/id_rsa",
    )
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "passwd", "id_rsa")
        assert len(server.urdf.refused) == 3


def test_mesh_symlink_leading_out_of_the_package_is_not_served(episode, tmp_path, home, package):
    (package / "meshes" / "evil.stl").symlink_to(home / ".ssh" / "id_rsa")
    (package / "meshes" / "passwd.dae").symlink_to("/etc/passwd")
    urdf = write_urdf(package, "package://arm_description/meshes/evil.stl", "../meshes/passwd.dae")
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "evil.stl", "passwd.dae", "id_rsa", "passwd")


def test_file_of_another_type_inside_the_package_is_not_served(episode, tmp_path, home, package):
    (package / "id_rsa").write_bytes(SECRET)
    urdf = write_urdf(package, "package://arm_description/id_rsa", "../package.xml")
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "id_rsa", "package.xml")
        assert any("not a mesh file" in reason for reason in server.urdf.refused)


def test_package_dirs_named_by_the_log_do_not_widen_what_is_served(
    episode, tmp_path, home, package
):
    (tmp_path / "ws" / "notes").mkdir()
    (tmp_path / "ws" / "notes" / "secret.stl").write_bytes(SECRET)
    urdf = write_urdf(
        package,
        "package://Documents/secret.stl",  # in the home directory the log names
        "package://home/Documents/secret.stl",  # in / the log names
        "package://notes/secret.stl",  # beside the package, but not one
    )
    dirs = [str(home), "/", str(tmp_path), str(tmp_path / "ws")]
    with serve(episode, tmp_path, urdf, package_dirs=dirs) as server:
        assert_serves_only_the_package_mesh(server, "secret.stl")
        assert len(server.urdf.refused) == 3


def test_fifo_and_device_meshes_are_never_read(episode, tmp_path, home, package):
    meshes = package / "meshes"
    os.mkfifo(meshes / "fifo.stl")
    for name in ("later_fifo.stl", "later_zero.stl", "later_other.stl"):
        (meshes / name).write_bytes(MESH)
    urdf = write_urdf(
        package,
        "/dev/zero",
        "package://arm_description/meshes/fifo.stl",
        "package://arm_description/meshes/later_fifo.stl",
        "package://arm_description/meshes/later_zero.stl",
        "package://arm_description/meshes/later_other.stl",
    )
    with serve(episode, tmp_path, urdf) as server:
        paths = mesh_paths(server)
        assert paths == [
            "/robot/meshes/0/base.stl",
            "/robot/meshes/1/later_fifo.stl",
            "/robot/meshes/2/later_zero.stl",
            "/robot/meshes/3/later_other.stl",
        ]
        (meshes / "later_fifo.stl").unlink()
        os.mkfifo(meshes / "later_fifo.stl")  # swapped after the start
        (meshes / "later_zero.stl").unlink()
        (meshes / "later_zero.stl").symlink_to("/dev/zero")
        (meshes / "later_other.stl").unlink()
        (meshes / "later_other.stl").write_bytes(SECRET)
        for path in paths[1:]:
            status, _, body = request(server, path)
            assert status in (404, 410) and SECRET not in body, path
        assert request(server, "/robot/meshes/0/base.stl")[2] == MESH  # still answering


def test_mesh_larger_than_the_bound_is_not_served(episode, tmp_path, home, package):
    with open(package / "meshes" / "huge.stl", "wb") as f:
        f.truncate(1 << 30)  # sparse: 1 GiB of nothing
    urdf = write_urdf(package, "package://arm_description/meshes/huge.stl")
    with serve(episode, tmp_path, urdf) as server:
        assert_serves_only_the_package_mesh(server, "huge.stl")
        assert "larger than" in server.urdf.refused[0]


@pytest.mark.parametrize("kind", ["dev_zero", "fifo", "huge"])
def test_robot_description_that_is_a_device_a_fifo_or_huge_is_one_line_and_exit_2(
    episode, tmp_path, kind
):
    if kind == "dev_zero":
        urdf = Path("/dev/zero")
    elif kind == "fifo":
        urdf = tmp_path / "arm.urdf"
        os.mkfifo(urdf)
    else:
        urdf = tmp_path / "arm.urdf"
        urdf.write_text(f'<robot name="arm"><!-- {"x" * (20 << 20)} --></robot>')
    log = relog(episode, tmp_path / "view.mcap", urdf_path=str(urdf))
    done = subprocess.run(  # at most 2 GiB: a regression must not take the machine's memory
        [*LIMITED, AMEX_LOG, "view", str(log), "--port", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr[-2000:]
    expected = "larger than 16 MiB" if kind == "huge" else "is not a regular file"
    assert done.stderr.startswith("amex-log: error: ") and expected in done.stderr


def test_robot_description_that_is_not_a_urdf_is_not_served(episode, tmp_path):
    other = tmp_path / "credentials.xml"
    other.write_text("<credentials><token>s3cr3t</token></credentials>")
    log = relog(episode, tmp_path / "view.mcap", urdf_path=str(other))
    with pytest.raises(LogError, match=r"not a URDF: its root element is <credentials>"):
        LogServer(read_log(log), port=0)


@pytest.fixture
def server(episode, tmp_path, home, package):
    """A server of the episode with the package's robot."""
    with serve(episode, tmp_path, write_urdf(package)) as server:
        yield server


def _paths(server):
    return ["/view.mcap", "/robot/robot.urdf", "/robot/meshes/0/base.stl", "/layout.json", "/"]


def test_page_of_another_origin_gets_403_and_no_cors_headers(server):
    other_port = f"http://127.0.0.1:{server.port + 1}"
    for origin in (EVIL, "null", other_port, f"http://evil.example:{server.port}"):
        for path in _paths(server):
            status, headers, body = request(server, path, {"Origin": origin})
            assert status == 403, (origin, path)
            assert "Access-Control-Allow-Origin" not in headers
            assert MESH not in body and b"MCAP" not in body and b"<robot" not in body


def test_preflight_of_another_origin_grants_nothing(server):
    asks = {
        "Origin": EVIL,
        "Access-Control-Request-Method": "GET",
        "Access-Control-Request-Headers": "range",
        "Access-Control-Request-Private-Network": "true",
    }
    for path in _paths(server):
        status, headers, _ = request(server, path, asks, method="OPTIONS")
        assert status == 403
        assert not [k for k in headers if k.lower().startswith("access-control-")]


def test_foxglove_and_this_server_get_cors_and_the_private_network_preflight(server):
    for origin in (
        "https://app.foxglove.dev",
        f"http://127.0.0.1:{server.port}",
        f"http://localhost:{server.port}",
    ):
        status, headers, body = request(
            server, "/view.mcap", {"Origin": origin, "Range": "bytes=0-7"}
        )
        assert status == 206 and body == b"\x89MCAP0\r\n"
        assert headers["Access-Control-Allow-Origin"] == origin
        assert "Content-Range" in headers["Access-Control-Expose-Headers"]
        asks = {"Origin": origin, "Access-Control-Request-Private-Network": "true",
                "Access-Control-Request-Headers": "range"}  # fmt: skip
        status, headers, _ = request(server, "/view.mcap", asks, method="OPTIONS")
        assert status == 204 and headers["Access-Control-Allow-Origin"] == origin
        assert headers["Access-Control-Allow-Private-Network"] == "true"
        assert headers["Access-Control-Allow-Headers"] == "range"


def test_foreign_host_header_is_refused_with_421(server):
    port = server.port
    for host in ("evil.example", f"evil.example:{port}", f"127.0.0.1.nip.io:{port}",
                 f"127.0.0.1:{port + 1}", "127.0.0.1", f"[::2]:{port}"):  # fmt: skip
        for path in _paths(server):
            status, _, body = request(server, path, host=host)
            assert status == 421, (host, path)
            assert MESH not in body and b"MCAP" not in body
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST:{port}"):
        assert request(server, "/layout.json", host=host)[0] == 200
    for raw in (b"GET /view.mcap HTTP/1.0\r\n\r\n",  # no Host at all
                b"GET /view.mcap HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nHost: evil.example\r\n\r\n"
                % port):  # fmt: skip
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(raw)
            assert s.recv(4096).split(b" ", 2)[1] == b"421"


def test_cross_site_request_without_an_origin_is_refused(server):
    embedded = {"Sec-Fetch-Site": "cross-site", "Sec-Fetch-Mode": "no-cors",
                "Sec-Fetch-Dest": "image"}  # fmt: skip
    for path in _paths(server):
        status, _, body = request(server, path, embedded)
        assert status == 403 and MESH not in body and b"MCAP" not in body
    navigated = {"Sec-Fetch-Site": "cross-site", "Sec-Fetch-Mode": "navigate"}
    assert request(server, "/", navigated)[0] == 200  # a link the user follows: nothing read
    assert request(server, "/", {"Sec-Fetch-Site": "none"})[0] == 200  # typed in


def test_non_loopback_host_needs_expose_on_network(episode, tmp_path):
    for host in ("0.0.0.0", "::", "192.0.2.1", "example.org"):
        done = subprocess.run(
            [AMEX_LOG, "view", str(episode), "--port", "0", "--host", host],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
        assert "not a loopback address" in done.stderr and "--expose-on-network" in done.stderr
    with pytest.raises(LogError, match="expose_on_network"):
        LogServer(read_log(episode), host="0.0.0.0", port=0)
    done = subprocess.run(  # with the flag it tries: 192.0.2.1 (TEST-NET) is not this machine
        [
            AMEX_LOG,
            "view",
            str(episode),
            "--port",
            "0",
            "--host",
            "192.0.2.1",
            "--expose-on-network",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert done.returncode == 2 and "cannot listen on 192.0.2.1" in done.stderr
    assert (
        "--expose-on-network"
        in subprocess.run([AMEX_LOG, "view", "--help"], capture_output=True, text=True).stdout
    )


@pytest.mark.slow
def test_many_idle_connections_hold_few_threads_and_are_closed(server):
    before = threading.active_count()
    idle = [socket.create_connection(("127.0.0.1", server.port), timeout=5) for _ in range(1000)]
    selector = selectors.DefaultSelector()
    try:
        time.sleep(0.5)
        assert threading.active_count() <= before + MAX_CONNECTIONS + 1
        for s in idle:
            s.setblocking(False)
            selector.register(s, selectors.EVENT_READ)
        left, busy = len(idle), 0
        deadline = time.monotonic() + 4 * IDLE_TIMEOUT + 10  # some wait in the accept queue
        while left and time.monotonic() < deadline:
            for key, _ in selector.select(timeout=0.5):
                try:
                    data = key.fileobj.recv(4096)
                except ConnectionResetError:
                    data = b""
                busy += data.startswith(b"HTTP/1.1 503 ")
                if not data:  # closed by the server
                    selector.unregister(key.fileobj)
                    left -= 1
        assert left == 0, f"{left} idle connections still open after {IDLE_TIMEOUT} s"
        assert busy > 0  # the connections beyond the bound were answered 503 at once
        while threading.active_count() > before and time.monotonic() < deadline:
            time.sleep(0.05)
        assert threading.active_count() == before
        assert request(server, "/layout.json")[0] == 200
    finally:
        selector.close()
        for s in idle:
            s.close()


@pytest.mark.parametrize(
    "header",
    ["bytes=" + "9" * 5000, "bytes=0-" + "9" * 5000, "bytes=-" + "9" * 5000,
     "bytes=99999999999999999999-", "bytes=0-1,4-5", "bytes=5-2", "bytes=-0", "bytes=-",
     "bytes=x-y", "bytes=--1", "bits=0-1", "bytes=1-2-3", ""],
)  # fmt: skip
def test_malformed_and_absurd_ranges_get_416_never_a_traceback(server, capfd, header):
    status, headers, _ = request(server, "/view.mcap", {"Range": header})
    assert status == 416 and headers["Content-Range"].startswith("bytes */")
    assert request(server, "/view.mcap", {"Range": "bytes=0-"})[0] == 206
    assert "Traceback" not in capfd.readouterr().err


def test_log_deleted_while_served_is_served_as_it_was(server, tmp_path):
    whole = (tmp_path / "view.mcap").read_bytes()
    (tmp_path / "view.mcap").unlink()
    status, _, body = request(server, "/view.mcap", {"Range": "bytes=0-7"})
    assert status == 206 and body == whole[:8]
    status, _, body = request(server, "/view.mcap")
    assert status == 200 and body == whole


@pytest.mark.parametrize("change", ["overwritten", "truncated", "appended"])
def test_log_changed_while_served_answers_410(server, tmp_path, change):
    log = tmp_path / "view.mcap"
    size = log.stat().st_size
    time.sleep(0.01)
    with open(log, "r+b") as f:
        if change == "overwritten":
            f.write(b"\0" * size)
        elif change == "truncated":
            f.truncate(size // 2)
        else:
            f.seek(0, 2)
            f.write(b"more")
    status, _, body = request(server, "/view.mcap", {"Range": "bytes=0-7"})
    assert status == 410 and b"changed" in body


def test_root_url_answers_with_the_links(episode):
    proc = subprocess.Popen(
        [AMEX_LOG, "view", str(episode), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        root = proc.stdout.readline().split(" on ")[1].split()[0]
        foxglove = proc.stdout.readline().split()[-1]
        host, port = root.removeprefix("http://").rstrip("/").split(":")
        conn = http.client.HTTPConnection(host, int(port), timeout=10)
        conn.request("GET", "/")
        response = conn.getresponse()
        page = response.read().decode()
        assert response.status == 200 and response.headers["Content-Type"] == "text/html"
        assert foxglove.replace("&", "&amp;") in page and "/layout.json" in page
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_studio_build_serves_only_its_own_files(episode, tmp_path, home):
    studio = tmp_path / "studio"
    assets = studio / "node_modules" / "@foxglove" / "studio-base" / "assets"
    assets.mkdir(parents=True)
    for name in ("index.html", "main.js"):
        (studio / name).write_text(name)
    for name in ("package.json", "check.mjs", "secret.txt"):
        (studio / name).write_bytes(SECRET)
    (assets / "index.js").write_text("index.js")
    (assets / "key.js").symlink_to(home / ".ssh" / "id_rsa")
    with LogServer(read_log(episode), port=0, studio_dir=studio) as server:
        for path in ("index.html", "main.js", "node_modules/@foxglove/studio-base/assets/index.js"):
            assert request(server, "/studio/" + path)[0] == 200
        for path in ("package.json", "check.mjs", "secret.txt",
                     "node_modules/@foxglove/studio-base/assets/../../../../secret.txt",
                     "node_modules/@foxglove/studio-base/assets/%2e%2e/%2e%2e/../../secret.txt",
                     "node_modules/@foxglove/studio-base/assets/key.js"):  # fmt: skip
            status, _, body = request(server, "/studio/" + path)
            assert status == 404 and SECRET not in body
