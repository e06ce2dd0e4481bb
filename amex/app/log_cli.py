"""``amex-log``: look into episode logs (``info``, ``plot``, ``export``, ``recover``, ``layout``).

Bad input (a missing, empty, non-MCAP or unrecoverably truncated or corrupt file, a bad option or
output name) prints one line ``amex-log: error: ...`` on stderr and exits with code 2;
``AMEX_DEBUG=1`` shows tracebacks. A truncated file (a run killed by SIGKILL) is read up to its
last complete chunk, a corrupt one (damaged bytes inside) without its damaged chunks, and every
command says which. Outputs are checked before anything is read: ``plot`` writes an image format
matplotlib knows (``-o out`` writes ``out.png`` and says so), ``recover`` a ``.mcap`` file,
``layout`` a ``.json`` file; ``recover`` and ``layout`` never overwrite an existing file.
matplotlib and pandas are imported only by the commands that need them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from amex.app.argparsing import OneLineParser, fail
from amex.core.errors import AmexError, LogError
from amex.log.files import refuse_existing, write_new
from amex.log.reader import LogData, read_log
from amex.log.recover import recover
from amex.log.serve import DEFAULT_PORT

PROG = "amex-log"
MAX_VIDEO_SIDE = 4096  # [px] one panel
MAX_VIDEO_FPS = 240.0  # [1/s]


def _fail(message: str) -> NoReturn:
    fail(PROG, message)


class _Parser(OneLineParser):
    """Sub-commands' usage errors too are reported as ``amex-log: error: ...``."""

    def error(self, message: str) -> NoReturn:
        _fail(f"{message} (see `{PROG} --help`)")


def _parser() -> _Parser:
    from amex import __version__

    parser = _Parser(prog=PROG, description="Inspect amex episode logs (MCAP).")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("info", help="channels, message counts, duration, config and outcome")
    p.add_argument("file", type=Path, metavar="FILE")
    p = sub.add_parser("plot", help="TCP and goal paths, distance, phase, joint accelerations")
    p.add_argument("file", type=Path, metavar="FILE")
    p.add_argument("-o", "--output", type=Path, metavar="PNG", help="default: FILE with .png")
    p = sub.add_parser("export", help="the JSON channels as tables (one file per topic)")
    p.add_argument("file", type=Path, metavar="FILE")
    p.add_argument("--format", choices=("csv", "parquet"), default="csv")
    p.add_argument("-o", "--output", type=Path, metavar="DIR", help="default: FILE_export/")
    p = sub.add_parser("recover", help="rewrite a truncated log as a valid indexed MCAP file")
    p.add_argument("file", type=Path, metavar="FILE")
    p.add_argument("-o", "--output", type=Path, metavar="OUT", required=True)
    p = sub.add_parser("layout", help="write a log's Foxglove layout (URDF as a file path)")
    p.add_argument("file", type=Path, metavar="FILE", nargs="?", help="default: --robot's")
    p.add_argument("-o", "--output", type=Path, metavar="JSON", default=Path("amex_layout.json"))
    p.add_argument("--robot", default="panda", help="without FILE: a catalogue robot (panda)")
    p = sub.add_parser(
        "view", help="serve a log, its robot and layout to Foxglove in the browser; print the URL"
    )
    p.add_argument("file", type=Path, metavar="FILE")
    p.add_argument("--port", type=int, default=DEFAULT_PORT, help="0: any free port")
    p.add_argument(
        "--host", default="127.0.0.1", help="loopback address to listen on (127.0.0.1, ::1)"
    )
    p.add_argument(
        "--expose-on-network",
        action="store_true",
        help="allow a --host that is not loopback (e.g. 0.0.0.0): everyone who can reach this "
        "machine on --port can then read the log, its robot description and meshes",
    )
    p.add_argument("--studio", type=Path, metavar="DIR", help="a Foxglove Studio web build")
    p = sub.add_parser(
        "video", help="film an episode (MuJoCo render, MP4); 2-3 logs of one env side by side"
    )
    p.add_argument("files", type=Path, nargs="+", metavar="FILE")
    p.add_argument("-o", "--output", type=Path, metavar="MP4", help="default: FILE with .mp4")
    p.add_argument("--fps", type=float, default=30.0, help="frames per second (default 30)")
    p.add_argument("--size", default="640x480", metavar="WxH", help="one panel [px]")
    p.add_argument("--speed", type=float, default=1.0, help="simulated s per s of film")
    p.add_argument(
        "--capsules", action="store_true", help="draw the collision capsules, not the meshes"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``amex-log``; returns the exit code (0, or 2 after a one-line error)."""
    args = _parser().parse_args(argv)
    commands = {
        "info": info,
        "plot": plot,
        "export": export,
        "recover": recover_cmd,
        "layout": layout,
        "view": view,
        "video": video,
    }
    try:
        commands[args.command](args)
    except BrokenPipeError:  # the reader went away (| head): stop quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except (AmexError, OSError) as e:
        if os.environ.get("AMEX_DEBUG"):
            raise
        where = f": {e.filename}" if isinstance(e, OSError) and e.filename else ""
        message = str(e) if isinstance(e, AmexError) else f"{e.strerror or e}{where}"
        _fail(message)
    return 0


def _truncation_line(data: LogData) -> str:
    return (
        f"recovered {data.message_count} messages from a {data.damage} file ({data.note}); "
        f"`{PROG} recover {data.path} -o OUT.mcap` writes them as a valid MCAP file"
    )


def _output(path: Path, suffixes: Sequence[str], what: str) -> Path:
    """``path`` if its suffix is one of ``suffixes``; a bare name gets the first one."""
    if not path.suffix:
        return path.with_name(path.name + suffixes[0])
    if path.suffix.lower() not in suffixes:
        raise LogError(
            f"invalid -o {str(path)!r}: {path.suffix!r} is not {what}; valid: a name ending in "
            + ", ".join(suffixes)
        )
    return path


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def info(args: argparse.Namespace) -> None:
    """Print what is in a log."""
    data = read_log(args.file)
    out = sys.stdout
    out.write(f"file       {data.path} ({data.size / 1e3:.1f} kB)\n")
    if data.damage:
        out.write(f"note       {_truncation_line(data)}\n")
    episode = data.metadata.get("episode", {})
    if episode:
        out.write("episode    " + " ".join(f"{k}={_fmt(v)}" for k, v in episode.items()) + "\n")
    out.write(
        f"duration   {data.duration:.3f} s of simulation "
        f"({data.start_time:.3f} .. {data.end_time:.3f} s)\n"
    )
    out.write(f"messages   {data.message_count} on {len(data.channels)} channels\n")
    width = max((len(t) for t in data.channels), default=5)
    for topic, ch in sorted(data.channels.items()):
        count, encoding = ch.message_count, ch.message_encoding
        out.write(f"  {topic:<{width}}  {count:6d}  {encoding:<8}  {ch.schema_name}\n")
    for name, record in data.metadata.items():
        if name in ("episode", "outcome"):
            continue
        text = " ".join(f"{k}={_short(v)}" for k, v in record.items())
        out.write(f"{name:<10} {text}\n")
    outcome = data.outcome
    if outcome is None and not data.is_amex_log:
        out.write("outcome    none: not an amex episode log (no episode metadata)\n")
    elif outcome is None:
        out.write("outcome    none: the episode did not finish writing its log\n")
    else:
        keys = (
            "status",
            "success",
            "final_distance",
            "final_time",
            "collided",
            "sum_sq_acc",
            "failure",
            "error",
            "signal",
        )
        shown = {k: outcome[k] for k in keys if k in outcome and outcome[k] not in ("", None)}
        out.write("outcome    " + " ".join(f"{k}={_fmt(v)}" for k, v in shown.items()) + "\n")


def _short(value: Any) -> str:
    text = json.dumps(value) if not isinstance(value, str) else value
    return text if len(text) <= 60 else text[:57] + "..."


def plot(args: argparse.Namespace) -> None:
    """Save a PNG: TCP/goal/reference paths, distance to goal, phase, joint accelerations."""
    from amex.log.plot import plot_episode

    output = args.output or args.file.with_suffix(".png")
    if output.is_dir():
        output = output / args.file.with_suffix(".png").name
    from matplotlib.backend_bases import FigureCanvasBase

    formats = [f".{ext}" for ext in FigureCanvasBase.get_supported_filetypes()]
    output = _output(output, [".png", *sorted(set(formats) - {".png"})], "an image format")
    refuse_existing(output)
    data = read_log(args.file)
    if "/tcp" not in data.channels or not data.messages["/tcp"]:
        raise LogError(f"{args.file} has no /tcp messages to plot (not an amex episode log?)")

    plot_episode(data, output)
    if data.damage:
        sys.stderr.write(f"{PROG}: note: {_truncation_line(data)}\n")
    sys.stdout.write(f"wrote {output}\n")


def export(args: argparse.Namespace) -> None:
    """Write each JSON topic, and the joint states, as a table (lists flattened: ``q_0``...)."""
    data = read_log(args.file)
    if args.format == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise LogError(
                "--format parquet needs pyarrow, which is not installed: pip install pyarrow "
                "(or use --format csv)"
            ) from None
    from amex.log.export import export_tables, undecodable

    out_dir = args.output or args.file.with_name(args.file.stem + "_export")
    written = export_tables(data, out_dir, args.format)
    for topic, (bad, total) in undecodable(data).items():
        sys.stderr.write(
            f"{PROG}: note: {bad} of {total} {topic} messages could not be decoded (damaged); "
            "left out of its table\n"
        )
    if data.damage:
        sys.stderr.write(f"{PROG}: note: {_truncation_line(data)}\n")
    for path in written:
        sys.stdout.write(f"wrote {path}\n")


def recover_cmd(args: argparse.Namespace) -> None:
    """Rewrite the readable part of a log as a valid indexed MCAP file."""
    output = _output(args.output, [".mcap"], "an MCAP file")
    data = recover(args.file, output)
    if data.damage:
        what = f"recovered {data.message_count} messages from a {data.damage} file ({data.note})"
    else:
        what = f"the file was intact; copied its {data.message_count} messages"
    sys.stdout.write(f"{what}; wrote {output}\n")


def layout(args: argparse.Namespace) -> None:
    """Write the log's Foxglove layout, its URDF layer reading the robot from a file path."""
    from amex.log.layout import build_layout

    if args.file is not None:
        layout = build_layout(read_log(args.file))
    else:
        from amex.robot import load_robot

        robot = load_robot(args.robot)
        layout = build_layout(
            None, robot={"name": robot.name, "urdf_path": robot.urdf_path,
                         "joint_names": list(robot.joint_names)},
        )  # fmt: skip
    output = _output(args.output, [".json"], "a JSON file")
    write_new(output, (json.dumps(layout, indent=2) + "\n").encode())
    sys.stdout.write(f"wrote {output}; in Foxglove desktop: Layouts > Import from file\n")


def view(args: argparse.Namespace) -> None:
    """Serve the log, its robot and layout; print the URLs; serve until Ctrl-C.

    Only to this machine unless ``--expose-on-network`` (``docs/viewers-security.md``).
    """
    from amex.log.serve import LogServer, is_loopback

    if not 0 <= args.port <= 65535:
        raise LogError(f"invalid --port {args.port}; valid: 0-65535 (0: any free port)")
    if not (args.expose_on_network or is_loopback(args.host)):
        raise LogError(
            f"--host {args.host} is not a loopback address: everyone who can reach it could read "
            "the log, its robot description and meshes; add --expose-on-network to allow that, "
            "or use --host 127.0.0.1"
        )
    data = read_log(args.file)
    try:
        server = LogServer(
            data,
            host=args.host,
            port=args.port,
            studio_dir=args.studio,
            expose_on_network=args.expose_on_network,
        )
    except OSError as e:
        raise LogError(
            f"cannot listen on {args.host}:{args.port} ({e.strerror}); try --port 0"
        ) from e
    urls = server.urls
    if args.expose_on_network and not is_loopback(args.host):
        sys.stderr.write(
            f"{PROG}: warning: listening on {args.host} port {server.port}: everyone who can "
            "reach it can read the log, its robot description and meshes\n"
        )
    if server.urdf is not None and server.urdf.refused:
        refused = server.urdf.refused
        more = f" (and {len(refused) - 1} more)" if len(refused) > 1 else ""
        sys.stderr.write(
            f"{PROG}: note: {len(refused)} mesh reference(s) of the robot description not "
            f"served, drawn as collision shapes: {refused[0]}{more}\n"
        )
    out = sys.stdout
    out.write(f"serving {data.path} ({data.size / 1e3:.0f} kB) on {urls.index} (Ctrl-C stops)\n")
    out.write(f"  Foxglove web app:  {urls.foxglove}\n")
    out.write(f"  its layout:        {urls.layout}  (save it, then Layouts > Import from file)\n")
    if urls.studio:
        out.write(f"  local Studio 1.48: {urls.studio}\n")
    if urls.urdf:
        out.write(f"  robot:             {urls.urdf}\n")
    out.flush()
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.close()


def video(args: argparse.Namespace) -> None:
    """Render the episode(s) into an MP4 film."""
    from amex.log.video import render_video

    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise LogError(f"invalid --size {args.size!r}; valid: WIDTHxHEIGHT, e.g. 640x480") from None
    if not (64 <= width <= MAX_VIDEO_SIDE and 64 <= height <= MAX_VIDEO_SIDE):
        raise LogError(
            f"invalid --size {args.size!r}; valid: WIDTHxHEIGHT, each 64..{MAX_VIDEO_SIDE} px"
        )
    if not 1.0 <= args.fps <= MAX_VIDEO_FPS:
        raise LogError(f"invalid --fps {args.fps:g}; valid: 1..{MAX_VIDEO_FPS:g} frames per second")
    if not 0.01 <= args.speed <= 100.0:
        raise LogError(f"invalid --speed {args.speed:g}; valid: 0.01..100 simulated s per s")
    output = _output(args.output or args.files[0].with_suffix(".mp4"), [".mp4"], "an MP4 file")
    geometry = "collision" if args.capsules else "visual"
    info = render_video(
        args.files, output, fps=args.fps, width=width, height=height, speed=args.speed,
        geometry=geometry,
    )  # fmt: skip
    if info.different_environments:
        sys.stderr.write(f"{PROG}: note: the logs are of different environments\n")
    sys.stdout.write(
        f"wrote {info.path} ({info.path.stat().st_size / 1e3:.0f} kB, {info.frames} frames, "
        f"{info.seconds:.1f} s, {info.width}x{info.height})\n"
    )


if __name__ == "__main__":
    sys.exit(main())
