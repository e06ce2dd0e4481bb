"""``amex-log view``: serve a log, its robot and a layout to Foxglove in a browser.

A small HTTP server (standard library only) that answers what a web viewer asks for: byte ranges
of the log (Foxglove reads an MCAP file's index, then the chunks it needs), the log's robot with
its meshes (:mod:`amex.log.urdf`), a layout (:mod:`amex.log.layout`), an index page at ``/`` and,
if installed, a local Foxglove Studio build; :attr:`LogServer.urls` gives the links. Nothing else,
and only to whom needs it: loopback unless ``expose_on_network``, the ``Host`` checked (421),
Foxglove's web app and this server as the only origins (:mod:`amex.log.serve_policy`), files
opened without links and bounded (:mod:`amex.log.serve_files`), :data:`MAX_CONNECTIONS` at once
with :data:`IDLE_TIMEOUT`. What is served, to whom and why: ``docs/viewers-security.md``.
"""

from __future__ import annotations

import html
import json
import re
import socket
import threading
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote, urlencode, urlsplit

from amex.core.errors import LogError
from amex.log.layout import build_layout
from amex.log.reader import LogData
from amex.log.serve_files import (
    STUDIO_DIR,
    FileResource,
    Opened,
    Refused,
    Site,
    Snapshot,
    TextResource,
    file_identity,
)
from amex.log.serve_policy import FOXGLOVE_ORIGIN, Policy, byte_range, is_loopback
from amex.log.urdf import MAX_MESH_BYTES, ViewerUrdf, viewer_urdf

FOXGLOVE_APP = FOXGLOVE_ORIGIN + "/"
DEFAULT_PORT = 8765
MAX_CONNECTIONS = 32  # at once; a browser opens at most 6 per server
IDLE_TIMEOUT = 5.0  # [s] for a request to arrive, on a new or a kept-alive connection
SEND_TIMEOUT = 60.0  # [s] for a stalled reader to take the next piece of an answer
TOKENS = re.compile(r"[A-Za-z0-9!#$%&'*+.^_`|~-]+(\s*,\s*[A-Za-z0-9!#$%&'*+.^_`|~-]+)*")
_BUSY = (
    b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\nContent-Length: 20\r\n"
    b"Retry-After: 1\r\nConnection: close\r\n\r\ntoo many connections"
)


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"
    server_version = "amex-log-view"
    _cors: str | None = None  # the request's allowed Origin, if any

    def version_string(self) -> str:
        """``Server:`` names no Python version."""
        return self.server_version

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib's name
        """Quiet: a viewer asks for hundreds of ranges."""

    def handle_one_request(self) -> None:
        self._cors = None
        self.connection.settimeout(self.server.idle_timeout)
        super().handle_one_request()

    def end_headers(self) -> None:
        if self._cors is not None:
            self.send_header("Access-Control-Allow-Origin", self._cors)
            self.send_header("Access-Control-Expose-Headers", "Content-Length, Content-Range")
        self.send_header("Vary", "Origin")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Cross-Origin-Resource-Policy", "same-origin")
        self.send_header("Cache-Control", "no-store")
        super().end_headers()

    def _refused(self) -> bool:
        """Answer and return True if this request must not be served (module notes)."""
        headers = self.headers
        if headers.get("Transfer-Encoding") or headers.get("Content-Length", "0") != "0":
            self.close_connection = True  # a body we do not read: no next request after it
        if not (self.path.startswith("/") or (self.command == "OPTIONS" and self.path == "*")):
            self._error(HTTPStatus.BAD_REQUEST, "only paths are served (origin-form targets)")
            return True
        hosts = headers.get_all("Host") or []
        if len(hosts) != 1 or not self.server.policy.host_ok(hosts[0]):
            self._error(
                HTTPStatus.MISDIRECTED_REQUEST,
                f"Host {', '.join(hosts) or '(none)'} is not this server; use the printed URLs",
            )
            return True
        origin = headers.get("Origin")
        if origin is not None:
            if not self.server.policy.origin_ok(origin):
                self._error(HTTPStatus.FORBIDDEN, f"origin {origin} may not read this server")
                return True
            self._cors = origin
        elif headers.get("Sec-Fetch-Site") in ("cross-site", "same-site") and (
            headers.get("Sec-Fetch-Mode") != "navigate"
        ):
            self._error(HTTPStatus.FORBIDDEN, "a cross-site request without an allowed origin")
            return True
        return False

    def do_OPTIONS(self) -> None:  # noqa: N802 - http.server's naming
        """CORS preflight of an allowed origin, including Chrome's private-network check."""
        if self._refused():
            return
        self.send_response(HTTPStatus.NO_CONTENT)
        self.send_header("Allow", "GET, HEAD, OPTIONS")
        if self._cors is not None:
            self.send_header("Access-Control-Allow-Methods", "GET, HEAD")
            asked = self.headers.get("Access-Control-Request-Headers", "")
            if TOKENS.fullmatch(asked):
                self.send_header("Access-Control-Allow-Headers", asked)
            if self.headers.get("Access-Control-Request-Private-Network") == "true":
                self.send_header("Access-Control-Allow-Private-Network", "true")
            self.send_header("Access-Control-Max-Age", "600")
        self.send_header("Content-Length", "0")
        self.end_headers()

    def do_HEAD(self) -> None:  # noqa: N802
        """Headers of GET."""
        self._answer(body=False)

    def do_GET(self) -> None:  # noqa: N802
        """A file, a byte range of it, or a generated text."""
        self._answer(body=True)

    def _answer(self, body: bool) -> None:
        if self._refused():
            return
        path = unquote(urlsplit(self.path).path)
        resource = self.server.site.find(path)
        if resource is None:
            self._error(HTTPStatus.NOT_FOUND, f"{path}: not served here")
            return
        try:
            with resource.opened() as opened:
                self._send(opened, body)
        except Refused as e:
            self._error(e.status, e.text, e.size)

    def _send(self, opened: Opened, body: bool) -> None:
        start, end, status = 0, opened.size - 1, HTTPStatus.OK
        header = self.headers.get("Range")
        if header is not None:
            start, end = byte_range(header, opened.size)
            status = HTTPStatus.PARTIAL_CONTENT
        self.send_response(status)
        self.send_header("Content-Type", opened.ctype)
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Content-Length", str(end - start + 1))
        if status == HTTPStatus.PARTIAL_CONTENT:
            self.send_header("Content-Range", f"bytes {start}-{end}/{opened.size}")
        self.end_headers()
        if not body:
            return
        self.connection.settimeout(self.server.send_timeout)
        offset = start
        try:
            while offset <= end:
                chunk = opened.read(offset, min(end + 1 - offset, 1 << 20))
                if not chunk:  # the file shrank under us: the answer is cut, say so by closing
                    self.close_connection = True
                    return
                self.wfile.write(chunk)
                offset += len(chunk)
        except (BrokenPipeError, ConnectionResetError):
            self.close_connection = True  # the viewer cancelled the request
        except OSError:  # a read error: the answer is cut
            self.close_connection = True

    def _error(self, status: HTTPStatus, text: str, size: int | None = None) -> None:
        data = (text + "\n").encode()
        self.send_response(status)
        if size is not None:
            self.send_header("Content-Range", f"bytes */{size}")
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)


class _Server(ThreadingHTTPServer):
    """Threads, at most ``max_connections`` of them; more connections are answered 503."""

    daemon_threads = True
    request_queue_size = 1024  # listen backlog: a burst waits here for its answer (or 503)
    site: Site
    policy: Policy

    def __init__(self, address: tuple[str, int], max_connections: int) -> None:
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        self.idle_timeout, self.send_timeout = IDLE_TIMEOUT, SEND_TIMEOUT
        self._slots = threading.BoundedSemaphore(max_connections)
        super().__init__(address, _Handler)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self._slots.acquire(blocking=False):
            try:
                request.setblocking(False)
                request.send(_BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()


@dataclass(frozen=True)
class ViewerUrls:
    """Where a served log can be opened."""

    log: str  # the MCAP file
    layout: str  # the layout JSON
    urdf: str  # the robot description
    foxglove: str  # Foxglove's web app with the log as a remote file
    studio: str | None  # the local Foxglove Studio with log and layout (if installed)
    index: str = ""  # the index page with these links


def _url_host(host: str) -> str:
    """``host`` as a URL writes it (a wildcard address: this machine's name)."""
    if host in ("", "0.0.0.0", "::"):
        host = socket.gethostname()
    return f"[{host}]" if ":" in host else host


class LogServer:
    """Serves one log (see the module notes) until :meth:`close`; use as a context manager.

    Args:
        data: the log, as read by :func:`amex.log.read_log`.
        host: interface to listen on: a loopback address unless ``expose_on_network``.
        port: TCP port; 0 picks a free one. The layout's URDF URL contains it.
        studio_dir: a Foxglove Studio web build to serve under ``/studio/`` (default
            ``tests/viewer/`` of this checkout, if ``make test-viewer`` installed it there).
        expose_on_network: allow a ``host`` that is not loopback: everyone who can reach it
            can then read the log, its robot description and meshes.

    Raises:
        LogError: a non-loopback ``host`` without ``expose_on_network``; the log is not a
            regular file; its robot description cannot be served (:func:`viewer_urdf`).
        OSError: the address cannot be listened on.
    """

    def __init__(
        self,
        data: LogData,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        studio_dir: Path | None = None,
        expose_on_network: bool = False,
    ) -> None:
        if not (expose_on_network or is_loopback(host)):
            raise LogError(
                f"{host} is not a loopback address: everyone who can reach it could read the "
                "log; pass expose_on_network=True (amex-log view --expose-on-network) to allow it"
            )
        host = host.strip("[]")
        self._snapshot = Snapshot(data.path)
        try:
            self._server = _Server((host, port), MAX_CONNECTIONS)
        except BaseException:
            self._snapshot.close()
            raise
        self.host, self.port = host, int(self._server.server_address[1])
        names = {"127.0.0.1", "localhost", "[::1]", _url_host(host).lower()}
        if expose_on_network:
            names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
        self._server.policy = Policy(self.port, frozenset(names), expose_on_network)
        self._thread: threading.Thread | None = None
        try:
            self._build(data, studio_dir)
        except BaseException:
            self._server.server_close()  # e.g. the log's URDF is missing: free the port
            self._snapshot.close()
            raise

    def _build(self, data: LogData, studio_dir: Path | None) -> None:
        base = f"http://{_url_host(self.host)}:{self.port}"
        log_path = "/" + quote(data.path.name)
        site = Site(resources={unquote(log_path): self._snapshot})
        robot = data.metadata.get("robot", {})
        urdf_url: str | None = None
        self.urdf: ViewerUrdf | None = None
        if robot.get("urdf_path"):
            self.urdf = viewer_urdf(
                robot["urdf_path"], f"{base}/robot/", robot.get("package_dirs") or ()
            )
            urdf = TextResource(self.urdf.text.encode(), "application/xml")
            site.resources["/robot/robot.urdf"] = urdf
            for name, path in self.urdf.files.items():
                identity = file_identity(path.stat())
                site.resources[f"/robot/{name}"] = FileResource(path, MAX_MESH_BYTES, identity)
            urdf_url = f"{base}/robot/robot.urdf"
        layout = build_layout(data, urdf_url=urdf_url)
        site.resources["/favicon.ico"] = TextResource(b"", "image/x-icon")
        site.resources["/layout.json"] = TextResource(
            json.dumps(layout, indent=2).encode(), "application/json"
        )
        studio = studio_dir if studio_dir is not None else STUDIO_DIR
        has_studio = (studio / "index.html").is_file() and (
            studio / "node_modules" / "@foxglove" / "studio-base" / "assets" / "index.js"
        ).is_file()
        if has_studio:
            site.studio = studio.resolve()
        self.layout = layout
        log_url = base + log_path
        query = {"ds": "remote-file", "ds.url": log_url}
        self.urls = ViewerUrls(
            log=log_url,
            layout=f"{base}/layout.json",
            urdf=urdf_url or "",
            foxglove=FOXGLOVE_APP + "?" + urlencode(query),
            studio=(
                f"{base}/studio/index.html?"
                + urlencode({**query, "amexLayout": f"{base}/layout.json"})
                if has_studio
                else None
            ),
            index=base + "/",
        )
        site.resources["/"] = TextResource(_index_page(data.path.name, self.urls), "text/html")
        self._server.site = site

    def start(self) -> LogServer:
        """Serve in a background thread (once); return self."""
        if self._thread is not None:
            return self
        self._thread = threading.Thread(
            target=self._server.serve_forever, name="amex-log-view", daemon=True
        )
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        """Serve in this thread until interrupted."""
        self._server.serve_forever()

    def close(self) -> None:
        """Stop serving and release the port."""
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=5)
            self._thread = None
        self._server.server_close()
        self._snapshot.close()

    def __enter__(self) -> LogServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()


def _index_page(name: str, urls: ViewerUrls) -> bytes:
    """The page at ``/``: the links ``amex-log view`` prints."""
    links = [
        ("Foxglove web app", urls.foxglove),
        ("local Foxglove Studio", urls.studio),
        ("the layout (save it, then Layouts > Import from file)", urls.layout),
        ("the robot description", urls.urdf),
        ("the log", urls.log),
    ]
    items = "".join(
        f'<li><a href="{html.escape(url)}">{html.escape(label)}</a></li>\n'
        for label, url in links
        if url
    )
    title = html.escape(f"amex-log view: {name}")
    return (
        f'<!doctype html>\n<html lang="en"><head><meta charset="utf-8"><title>{title}</title>'
        f"</head>\n<body><h1>{title}</h1>\n<ul>\n{items}</ul></body></html>\n"
    ).encode()
