"""Fault injection, amex-log's outputs and the episode log on a full disk: nothing replaced,
nothing cut under a final name, one line naming the file and the cause."""

import subprocess
import sys
from pathlib import Path

import pytest

from amex.app.log_cli import main
from amex.experiment.config import RunConfig
from amex.experiment.runner import prepare, run_one
from amex.methods.dmp import DMPConfig

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


@pytest.fixture(scope="module")
def log_file(tmp_path_factory):
    config = RunConfig(task=3, max_time=1.0)
    config.method = DMPConfig()
    path = tmp_path_factory.mktemp("log") / "episode_000.mcap"
    run_one(config, prepare(config), 0, path)
    return path


def _run(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("command", "target"),
    [("plot", "figure.png"), ("export", "tables/tcp.csv"), ("video", "film.mp4")],
)
def test_an_existing_output_is_never_replaced(log_file, tmp_path, capsys, command, target):
    path = tmp_path / target
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("precious")
    output = path.parent if command == "export" else path
    code, out, err = _run([command, log_file, "-o", output], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "already exists" in err and path.read_text() == "precious"


@pytest.mark.parametrize("command", ["plot", "export"])
def test_a_full_disk_leaves_no_cut_output_and_names_the_cause(
    log_file, small_disk, capsys, command
):
    mount, fill = small_disk
    filler = fill(leave=8 * 1024)
    target = mount / ("figure.png" if command == "plot" else "tables")
    code, out, err = _run([command, log_file, "-o", target], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "No space left on device" in err and "None" not in err
    left = [p for p in mount.rglob("*") if p.is_file() and p != filler]
    assert all(p.stat().st_size > 0 and not p.name.startswith(".") for p in left), left
    if command == "plot":
        assert not (mount / "figure.png").exists()


def test_a_full_disk_while_logging_stops_the_run_in_one_line_and_keeps_the_rows(small_disk):
    mount, _ = small_disk  # 256 KiB: the first log fills it
    run_dir = mount / "run"
    done = subprocess.run(
        [
            AMEX_RUN,
            "task=3",
            "method=dmp",
            "episodes=3",
            "max_time=3",
            "log=full",
            f"hydra.run.dir={run_dir}",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=300,
    )
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) <= 3, done.stderr[-3000:]
    last = lines[-1]
    assert "No space left on device" in last and "episode_000.mcap.part" in last
    assert "the same command to resume" in last
    assert "panic" not in done.stderr.lower() and "Traceback" not in done.stderr
    assert not (run_dir / "logs" / "episode_000.mcap").exists()  # a cut log keeps .part
