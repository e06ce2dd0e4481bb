"""``amex-log view``: serve a log, its robot and a layout to Foxglove in a browser.

A small HTTP server on the loopback interface (standard library only) that answers what a web
viewer asks for: byte ranges (Foxglove reads an MCAP file's index, then the chunks it needs),
CORS headers on every answer and on preflights (``Access-Control-Allow-Private-Network`` too, so
that the https web app may read from the local machine). It serves

========================= ===========================================================
``/<log name>.mcap``      the log
``/robot/robot.urdf``     the log's robot, meshes rewritten to URLs (:mod:`amex.log.urdf`)
``/robot/meshes/...``     the meshes it uses
``/layout.json``          the layout for this log (:mod:`amex.log.layout`), URDF from above
``/studio/...``           a local Foxglove Studio web build, if one is installed (``tests/viewer/``)
========================= ===========================================================

and :func:`viewer_urls` gives the links that open them: Foxglove's web app with the log as a
remote file, and the local Studio with the log and the layout preselected.
"""

from __future__ import annotations

import json
import mimetypes
import re
import threading
from dataclasses import dataclass, field
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote, urlencode, urlsplit

from amex.log.layout import build_layout
from amex.log.reader import LogData
from amex.log.urdf import viewer_urdf

FOXGLOVE_APP = "https://app.foxglove.dev/"
DEFAULT_PORT = 8765
# make test-viewer installs it
STUDIO_DIR = Path(__file__).resolve().parents[2] / "tests" / "viewer"
_RANGE = re.compile(r"bytes=(\d*)-(\d*)$")


@dataclass
class Site:
    """What the server answers: files by URL path, and generated texts by URL path."""

    files: dict[str, Path] = field(default_factory=dict)
    texts: dict[str, tuple[bytes, str]] = field(default_factory=dict)
    static_dirs: dict[str, Path] = field(default_factory=dict)

    def find(self, path: str) -> Path | tuple[bytes, str] | None:
        """The file or (content, type) at URL ``path``; None if there is none."""
        if path in self.texts:
            return self.texts[path]
        if path in self.files:
            return self.files[path]
        for prefix, root in self.static_dirs.items():
            if path.startswith(prefix):
                target = (root / path[len(prefix) :]).resolve()
                if target.is_relative_to(root.resolve()) and target.is_file():
                    return target
        return None


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib's name
        """Quiet: a viewer asks for hundreds of ranges."""

    def end_headers(self) -> None:
        self.send_header("Access-Control-Allow-Origin", "*")
        self.send_header("Access-Control-Expose-Headers", "Content-Length, Content-Range")
        super().end_headers()

    def do_OPTIONS(self) -> None:  # noqa: N802 - http.server's naming
        """CORS preflight, including Chrome's private-network access check."""
        self.send_response(HTTPStatus.NO_CONTENT)
        self.send_header("Access-Control-Allow-Methods", "GET, HEAD, OPTIONS")
        self.send_header("Access-Control-Allow-Headers", "*")
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
        path = unquote(urlsplit(self.path).path)
        found = self.server.site.find(path)
        if found is None:
            self._error(HTTPStatus.NOT_FOUND, f"{path}: not served here")
            return
        if isinstance(found, tuple):
            content, ctype = found
            size = len(content)
        else:
            ctype = mimetypes.guess_type(found.name)[0] or "application/octet-stream"
            size = found.stat().st_size
        start, end = 0, size - 1
        status = HTTPStatus.OK
        header = self.headers.get("Range")
        if header:
            m = _RANGE.match(header.strip())
            if m is None or (not m.group(1) and not m.group(2)):
                self._error(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE, "bad range", size)
                return
            if m.group(1):
                start = int(m.group(1))
                end = min(int(m.group(2)), size - 1) if m.group(2) else size - 1
            else:  # the last n bytes
                start = max(size - int(m.group(2)), 0)
            if start >= size or start > end:
                self._error(HTTPStatus.REQUESTED_RANGE_NOT_SATISFIABLE, "range outside", size)
                return
            status = HTTPStatus.PARTIAL_CONTENT
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Length", str(end - start + 1))
        if status == HTTPStatus.PARTIAL_CONTENT:
            self.send_header("Content-Range", f"bytes {start}-{end}/{size}")
        self.end_headers()
        if not body:
            return
        try:
            if isinstance(found, tuple):
                self.wfile.write(found[0][start : end + 1])
                return
            with open(found, "rb") as f:
                f.seek(start)
                left = end - start + 1
                while left > 0:
                    chunk = f.read(min(left, 1 << 20))
                    if not chunk:
                        break
                    self.wfile.write(chunk)
                    left -= len(chunk)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the viewer cancelled the request

    def _error(self, status: HTTPStatus, text: str, size: int | None = None) -> None:
        data = (text + "\n").encode()
        self.send_response(status)
        if size is not None:
            self.send_header("Content-Range", f"bytes */{size}")
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    site: Site


@dataclass(frozen=True)
class ViewerUrls:
    """Where a served log can be opened."""

    log: str  # the MCAP file
    layout: str  # the layout JSON
    urdf: str  # the robot description
    foxglove: str  # Foxglove's web app with the log as a remote file
    studio: str | None  # the local Foxglove Studio with log and layout (if installed)


class LogServer:
    """Serves one log (see the module notes) until :meth:`close`; use as a context manager.

    Args:
        data: the log, as read by :func:`amex.log.read_log`.
        host: interface to listen on (default loopback only).
        port: TCP port; 0 picks a free one. The layout's URDF URL contains it.
        studio_dir: a Foxglove Studio web build to serve under ``/studio/`` (default
            ``tests/viewer/`` of this checkout, if ``make test-viewer`` installed it there).
    """

    def __init__(
        self,
        data: LogData,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        studio_dir: Path | None = None,
    ) -> None:
        self._server = _Server((host, port), _Handler)
        self.host, self.port = host, int(self._server.server_address[1])
        try:
            self._build(data, host, studio_dir)
        except BaseException:
            self._server.server_close()  # e.g. the log's URDF is missing: free the port
            raise
        self._thread: threading.Thread | None = None

    def _build(self, data: LogData, host: str, studio_dir: Path | None) -> None:
        base = f"http://{host}:{self.port}"
        log_path = "/" + quote(data.path.name)
        site = Site(files={unquote(log_path): data.path})
        robot = data.metadata.get("robot", {})
        urdf_url: str | None = None
        if robot.get("urdf_path"):
            urdf = viewer_urdf(
                robot["urdf_path"], f"{base}/robot/", robot.get("package_dirs") or ()
            )
            site.texts["/robot/robot.urdf"] = (urdf.text.encode(), "application/xml")
            site.files.update({f"/robot/{k}": v for k, v in urdf.files.items()})
            urdf_url = f"{base}/robot/robot.urdf"
        layout = build_layout(data, urdf_url=urdf_url)
        site.texts["/favicon.ico"] = (b"", "image/x-icon")
        site.texts["/layout.json"] = (json.dumps(layout, indent=2).encode(), "application/json")
        studio = studio_dir if studio_dir is not None else STUDIO_DIR
        has_studio = (studio / "index.html").is_file() and (
            studio / "node_modules" / "@foxglove" / "studio-base" / "assets" / "index.js"
        ).is_file()
        if has_studio:
            site.static_dirs["/studio/"] = studio
        self._server.site = site
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
        )

    def start(self) -> LogServer:
        """Serve in a background thread; return self."""
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

    def __enter__(self) -> LogServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
