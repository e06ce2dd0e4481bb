"""``amex-live [overrides] [--port N] [--host H] [--speed F] ...``: a live episode in the browser.

The overrides are ``amex-run``'s (the same composition and checks: robot, task's scene, method,
rates, controller, perception); the page (viser, served with its client, no download) shows the
episode in real time and lets you move the goal and the obstacles, switch the method, reset,
pause, step and record (:mod:`amex.app.live.page`). The page listens on 127.0.0.1 only unless
``--allow-remote`` is given with a non-loopback ``--host``: whoever reaches the page drives the
simulation and writes logs into ``--record-dir``. Ctrl-C stops it (a recording is finished).
Bad input is one line ``amex-live: error: ...`` on stderr and exit code 2; ``AMEX_DEBUG=1``
shows tracebacks.
"""

from __future__ import annotations

import ipaddress
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: tiny linear algebra, no thread pools

import argparse  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import threading  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

from amex.app.argparsing import OneLineParser, fail  # noqa: E402
from amex.core.errors import AmexError, UsageError  # noqa: E402

PROG = "amex-live"
DEFAULT_PORT = 8090


def parser() -> OneLineParser:
    """The command line (every argument that is no flag is a configuration override)."""
    p = OneLineParser(
        prog=PROG,
        description="Run one episode at a time in real time and show it in the browser: drag "
        "the goal and the obstacles, switch the method, reset, pause, step, record.",
        epilog="Overrides as for amex-run, e.g. `amex-live task=3 method=dmp perception.latency"
        "=0.05`. Open the printed URL (over SSH: ssh -L PORT:127.0.0.1:PORT host).",
    )
    p.add_argument("overrides", nargs="*", metavar="OVERRIDE", help="key=value, as for amex-run")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"default {DEFAULT_PORT}")
    p.add_argument("--host", default="127.0.0.1", help="interface (default: loopback only)")
    p.add_argument(
        "--allow-remote",
        action="store_true",
        help="allow a non-loopback --host: anyone who reaches it can drive the simulation "
        "(move the goal, switch methods) and write logs into --record-dir",
    )
    p.add_argument("--speed", type=float, default=1.0, help="simulated s per wall s (default 1)")
    p.add_argument("--max-time", type=float, default=300.0, help="episode time limit [s]")
    p.add_argument("--record-dir", type=Path, default=Path("runs/live"), help="for Record")
    p.add_argument("--paused", action="store_true", help="start paused")
    return p


def check_host(host: str, allow_remote: bool) -> None:
    """Refuse a non-loopback ``host`` unless ``allow_remote`` (:class:`UsageError`)."""
    if host == "localhost":
        return
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = False
    if not loopback and not allow_remote:
        raise UsageError(
            f"--host {host} would serve the live page beyond this machine: whoever reaches it can "
            "drive the simulation and write logs; add --allow-remote to do that, or keep the "
            "default 127.0.0.1 and forward the port (ssh -L)"
        )


def serve(args: argparse.Namespace, ready: threading.Event | None = None) -> Any:
    """Build the session and the page and start them; returns ``(server, session, page)``."""
    import viser

    from amex.app.live.page import LivePage
    from amex.app.live.session import LiveSession

    check_host(args.host, args.allow_remote)
    if not (args.speed > 0 and args.max_time > 0):
        raise UsageError("invalid --speed or --max-time; valid: numbers > 0")
    session = LiveSession(
        list(args.overrides), args.max_time, args.speed, args.record_dir, args.paused
    )
    try:
        server = viser.ViserServer(host=args.host, port=args.port, verbose=False)
    except OSError as e:
        message = f"cannot listen on {args.host}:{args.port} ({e.strerror}); try --port 0"
        raise UsageError(message) from e
    server.gui.set_panel_label("amex live")
    page = LivePage(server, session)
    session.start()
    page.start()
    if ready is not None:
        ready.set()
    return server, session, page


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``amex-live``."""
    args = parser().parse_args(argv)
    debug = os.environ.get("AMEX_DEBUG") == "1"
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        server, session, page = serve(args)
    except AmexError as e:
        if debug:
            raise
        fail(PROG, str(e))
    port = server.get_port()
    print(f"{PROG}: serving on http://{args.host}:{port} (Ctrl-C stops)", flush=True)
    try:
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        page.close()
        session.close()
        server.stop()
    if session.last_log is not None:
        print(f"{PROG}: last recording {session.last_log}", file=sys.stderr)
    return 0
