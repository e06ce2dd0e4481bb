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
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from amex.app.argparsing import OneLineParser, fail
from amex.core.durable import create_new
from amex.core.errors import AmexError, LogError, LogExistsError, WriteError
from amex.log.plot3d import set_equal_axes_3d
from amex.log.reader import LogData, read_log, recover, topics_with_numbers
from amex.log.serve import DEFAULT_PORT

PROG = "amex-log"


def _fail(message: str) -> NoReturn:
    fail(PROG, message)


class _Parser(OneLineParser):
    """Sub-commands' usage errors too are reported as ``amex-log: error: ...``."""

    def error(self, message: str) -> NoReturn:
        _fail(f"{message} (see `{PROG} --help`)")


def _parser() -> _Parser:
    parser = _Parser(prog=PROG, description="Inspect amex episode logs (MCAP).")
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
    p.add_argument("--host", default="127.0.0.1", help="interface to listen on")
    p.add_argument("--studio", type=Path, metavar="DIR", help="a Foxglove Studio web build")
    p = sub.add_parser(
        "video", help="film an episode (MuJoCo render, MP4); 2-3 logs of one env side by side"
    )
    p.add_argument("files", type=Path, nargs="+", metavar="FILE")
    p.add_argument("-o", "--output", type=Path, metavar="MP4", help="default: FILE with .mp4")
    p.add_argument("--fps", type=float, default=30.0, help="frames per second (default 30)")
    p.add_argument("--size", default="640x480", metavar="WxH", help="one panel [px]")
    p.add_argument("--speed", type=float, default=1.0, help="simulated s per s of film")
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
        message = str(e) if isinstance(e, AmexError) else f"{e.strerror or e}: {e.filename}"
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
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output = args.output or args.file.with_suffix(".png")
    if output.is_dir():
        output = output / args.file.with_suffix(".png").name
    from matplotlib.backend_bases import FigureCanvasBase

    formats = [f".{ext}" for ext in FigureCanvasBase.get_supported_filetypes()]
    output = _output(output, [".png", *sorted(set(formats) - {".png"})], "an image format")
    data = read_log(args.file)
    if "/tcp" not in data.channels or not data.messages["/tcp"]:
        raise LogError(f"{args.file} has no /tcp messages to plot (not an amex episode log?)")

    fig = plt.figure(figsize=(12, 8.5), layout="constrained")
    ax3 = fig.add_subplot(2, 2, 1, projection="3d")
    draw_paths(ax3, data)
    t = data.times("/goal")
    ax = fig.add_subplot(2, 2, 2)
    ax.plot(t, data.series("/goal", "distance"), color="C0")
    ax.axhline(0.03, color="0.5", ls="--", lw=1, label="success radius 0.03 m")
    ax.set(xlabel="t [s]", ylabel="distance TCP - goal [m]", title="Distance to goal")
    ax.legend(loc="upper right")
    ax = fig.add_subplot(2, 2, 3)
    phase_keys = [k for k in ("s", "phase", "phase_rate", "index") if _has(data, "/method", k)]
    title = "Method internals: phase (AMEX s, DMP x)"
    scaled = not phase_keys  # no phase: every number, each divided by its largest magnitude
    if scaled:
        phase_keys = [k for k in _scalar_keys(data, "/method") if k != "t"]
        title = "Method internals, each divided by its largest |value|"
    for key in phase_keys:
        values = data.series("/method", key)
        peak = float(np.nanmax(np.abs(values))) if scaled and np.isfinite(values).any() else 1.0
        label = f"{key} / {peak:.3g}" if scaled else key
        ax.plot(data.times("/method"), values / (peak or 1.0), label=label)
    ax.set(xlabel="t [s]", title=title)
    if phase_keys:
        ax.legend(loc="best")
    else:
        ax.text(0.5, 0.5, "no numeric internals logged", ha="center", transform=ax.transAxes)
    ax = fig.add_subplot(2, 2, 4)
    qdd = data.joints("acceleration")
    if qdd.size:
        for j in range(qdd.shape[1]):
            ax.plot(data.times("/joint_states"), qdd[:, j], lw=1, label=f"joint {j + 1}")
        ax.legend(loc="upper right", ncol=2, fontsize="small")
    ax.set(xlabel="t [s]", ylabel="q_ddot [rad/s^2]", title="Joint accelerations (100 Hz)")
    fig.suptitle(_title(data))
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=110)
    plt.close(fig)
    if data.damage:
        sys.stderr.write(f"{PROG}: note: {_truncation_line(data)}\n")
    sys.stdout.write(f"wrote {output}\n")


def _title(data: LogData) -> str:
    episode = data.metadata.get("episode", {})
    name = " ".join(f"{k}={episode[k]}" for k in ("task", "method", "env", "seed") if k in episode)
    outcome = data.outcome or {}
    tail = ""
    if "success" in outcome:
        tail = (
            f" - {'success' if outcome['success'] else 'no success'}, final distance "
            f"{outcome.get('final_distance', math.nan):.3f} m at "
            f"{outcome.get('final_time', math.nan):.2f} s"
        )
    if data.damage:
        tail += f" (recovered from a {data.damage} file)"
    return (name or str(data.path.name)) + tail


def _has(data: LogData, topic: str, key: str) -> bool:
    return any(isinstance(m.data, dict) and key in m.data for m in data.messages.get(topic, []))


def _scalar_keys(data: LogData, topic: str) -> list[str]:
    keys: dict[str, None] = {}
    for m in data.messages.get(topic, []):
        if isinstance(m.data, dict):
            for k, v in m.data.items():
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    keys[k] = None
    return list(keys)


def draw_paths(ax: Any, data: LogData) -> None:
    """On 3-D axes: reference plan, executed TCP path, goal path and obstacle spheres."""
    import numpy as np

    ref = data.reference_path()
    tcp = data.series("/tcp", "position")
    goal = data.series("/goal", "position")
    if len(ref):
        ax.plot(*ref.T, color="0.45", ls="--", lw=1.5, label="reference plan")
    ax.plot(*tcp.T, color="C0", lw=2, label="executed TCP path")
    ax.plot(*goal.T, color="C2", lw=2, label="goal path")
    ax.scatter(*goal[-1], color="C2", s=40, marker="o", label="goal (end)")
    ax.scatter(*tcp[0], color="k", s=25, marker="s", label="start")
    scenario = data.metadata.get("scenario", {})
    centers = np.asarray(scenario.get("obstacle_start") or np.zeros((0, 3)), dtype=float)
    radii = np.asarray(scenario.get("obstacle_radii") or [], dtype=float)
    u, v = np.mgrid[0 : 2 * np.pi : 24j, 0 : np.pi : 12j]
    for c, r in zip(centers.reshape(-1, 3), radii, strict=False):
        ax.plot_surface(
            c[0] + r * np.cos(u) * np.sin(v),
            c[1] + r * np.sin(u) * np.sin(v),
            c[2] + r * np.cos(v),
            color="C3",
            alpha=0.3,
            linewidth=0,
        )
    if len(radii):
        ax.plot([], [], color="C3", lw=6, alpha=0.4, label="obstacle")
    points = np.concatenate([p for p in (ref, tcp, goal) if len(p)])
    set_equal_axes_3d(ax, points, pad=1.1, min_half=0.05)
    ax.legend(loc="center left", bbox_to_anchor=(1.2, 0.5), fontsize="small")
    ax.set_title("TCP and goal in task space")


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
    import pandas as pd

    out_dir = args.output or args.file.with_name(args.file.stem + "_export")
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    tables: dict[str, Any] = {t: _table(data, t) for t in topics_with_numbers(data)}
    if data.channels.get("/joint_states"):
        tables["/joints"] = _joint_table(data)
    for topic, rows in tables.items():
        frame = pd.DataFrame(rows)
        name = topic.strip("/").replace("/", "_") or "root"
        path = out_dir / f"{name}.{args.format}"
        if args.format == "csv":
            frame.to_csv(path, index=False)
        else:
            frame.to_parquet(path, index=False)
        written.append(path)
    meta = out_dir / "metadata.json"
    meta.write_text(
        json.dumps(
            {"truncated": data.truncated, "corrupt": data.corrupt, "note": data.note}
            | data.metadata,
            indent=2,
        )
        + "\n"
    )
    written.append(meta)
    if data.damage:
        sys.stderr.write(f"{PROG}: note: {_truncation_line(data)}\n")
    for path in written:
        sys.stdout.write(f"wrote {path}\n")


def _table(data: LogData, topic: str) -> list[dict[str, Any]]:
    """Rows of ``topic``: ``time`` [s] plus the flattened message (lists of lists: rows)."""
    rows: list[dict[str, Any]] = []
    for m in data.messages[topic]:
        if not isinstance(m.data, dict):
            continue
        nested = {k: v for k, v in m.data.items() if _is_matrix(v)}
        if nested:  # e.g. /reference: one row per sample
            for key, matrix in nested.items():
                for i, sample in enumerate(matrix):
                    flat = {"index": i, **_flatten(sample, key)}
                    if "dt" in m.data:
                        flat = {"time": i * m.data["dt"], **flat}
                    rows.append(flat)
            continue
        row: dict[str, Any] = {"time": m.log_time * 1e-9}
        for key, value in m.data.items():
            if isinstance(value, list):
                row.update({f"{key}_{j}": x for j, x in enumerate(value)})
            elif isinstance(value, dict):
                row[key] = json.dumps(value)
            else:
                row[key] = value
        rows.append(row)
    return rows


def _joint_table(data: LogData) -> dict[str, Any]:
    """``/joint_states`` as columns ``time, q_0.., qd_0.., qdd_0.., tau_0..``."""
    table: dict[str, Any] = {"time": data.times("/joint_states")}
    for prefix, field in (("q", "position"), ("qd", "velocity"), ("qdd", "acceleration"),
                          ("tau", "effort")):  # fmt: skip
        values = data.joints(field)
        table.update({f"{prefix}_{j}": values[:, j] for j in range(values.shape[1])})
    return table


def _is_matrix(value: Any) -> bool:
    """A list of lists or of objects (``/reference``'s samples)."""
    return isinstance(value, list) and bool(value) and isinstance(value[0], (list, dict))


def _flatten(sample: Any, key: str) -> dict[str, Any]:
    """One sample as columns: a list as ``key_0, key_1..``, an object's lists as ``name_0..``."""
    if isinstance(sample, list):
        return {f"{key}_{j}": x for j, x in enumerate(sample)}
    flat: dict[str, Any] = {}
    for name, value in sample.items():
        if isinstance(value, list):
            flat.update({f"{name}_{j}": x for j, x in enumerate(value)})
        else:
            flat[name] = value
    return flat


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
    output.parent.mkdir(parents=True, exist_ok=True)
    try:
        create_new(output, (json.dumps(layout, indent=2) + "\n").encode())
    except FileExistsError:
        raise LogExistsError(f"output file {output} already exists; not overwriting it") from None
    except WriteError as e:
        raise LogError(str(e)) from e
    sys.stdout.write(f"wrote {output}; in Foxglove desktop: Layouts > Import from file\n")


def view(args: argparse.Namespace) -> None:
    """Serve the log, its robot and layout; print the URLs; serve until Ctrl-C."""
    from amex.log.serve import LogServer

    data = read_log(args.file)
    if not 0 <= args.port <= 65535:
        raise LogError(f"invalid --port {args.port}; valid: 0-65535 (0: any free port)")
    try:
        server = LogServer(data, host=args.host, port=args.port, studio_dir=args.studio)
    except OSError as e:
        raise LogError(
            f"cannot listen on {args.host}:{args.port} ({e.strerror}); try --port 0"
        ) from e
    urls = server.urls
    out = sys.stdout
    out.write(f"serving {data.path} ({data.size / 1e3:.0f} kB) on http://{args.host}:"
              f"{server.port}/ (Ctrl-C stops)\n")  # fmt: skip
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
    output = _output(args.output or args.files[0].with_suffix(".mp4"), [".mp4"], "an MP4 file")
    info = render_video(
        args.files, output, fps=args.fps, width=width, height=height, speed=args.speed
    )
    if info.different_environments:
        sys.stderr.write(f"{PROG}: note: the logs are of different environments\n")
    sys.stdout.write(
        f"wrote {info.path} ({info.path.stat().st_size / 1e3:.0f} kB, {info.frames} frames, "
        f"{info.seconds:.1f} s, {info.width}x{info.height})\n"
    )


if __name__ == "__main__":
    sys.exit(main())
