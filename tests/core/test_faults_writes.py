"""Fault injection, data loss: short writes, full disks, overwrites; real files and processes."""

import csv
import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from amex.core.durable import append_durably, create_new, replace_durably
from amex.core.errors import WriteError
from amex.experiment.store import EpisodeStore, read_rows
from amex.sim.metrics import EpisodeResult

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


def _result(env: int) -> EpisodeResult:
    return EpisodeResult(1, "track", env, 0, True, True, False, 0.01, 3.0, 12.5, 1e-5, 2e-5, "")


def _store(path: Path) -> EpisodeStore:
    return EpisodeStore(path, "c0ffee", "5ce7e")


def test_a_short_write_is_continued_not_glued_to_the_next_row(tmp_path, monkeypatch):
    store = _store(tmp_path / "episodes.csv")
    real_write = os.write
    monkeypatch.setattr(os, "write", lambda fd, data: real_write(fd, bytes(data)[:7]))
    for env in range(3):
        store.append(_result(env))
    monkeypatch.undo()
    assert [r["env"] for r in read_rows(store.path)] == ["0", "1", "2"]


@pytest.mark.parametrize("failure", ["no_progress", "enospc_after_part", "fsync"])
def test_a_failed_write_raises_and_leaves_no_torn_row(tmp_path, monkeypatch, failure):
    store = _store(tmp_path / "episodes.csv")
    store.append(_result(0))
    before = store.path.read_bytes()
    real_write = os.write
    calls = []

    def write(fd, data):
        calls.append(len(data))
        if failure == "no_progress":
            return 0
        if failure == "enospc_after_part" and len(calls) > 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, bytes(data)[:9])

    def fsync(fd):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(os, "write", write if failure != "fsync" else real_write)
    if failure == "fsync":
        monkeypatch.setattr(os, "fsync", fsync)
    with pytest.raises(WriteError, match="cannot write .*episodes.csv"):
        store.append(_result(1))
    monkeypatch.undo()
    assert store.path.read_bytes() == before  # cut back: resumable as it was
    again = _store(store.path)
    assert sorted(again.done) == [0]
    again.append(_result(1))
    assert [r["env"] for r in read_rows(store.path)] == ["0", "1"]


def test_a_full_disk_stops_appends_and_the_file_resumes_once_space_is_freed(small_disk):
    disk, fill = small_disk
    store = _store(disk / "episodes.csv")
    filler = fill(leave=0)
    written = 0
    with pytest.raises(WriteError, match="No space left on device"):
        for env in range(1000):
            store.append(_result(env))
            written += 1
    rows = read_rows(store.path)
    assert len(rows) == written and store.path.read_bytes().endswith(b"\n")
    filler.unlink()
    again = _store(store.path)
    assert sorted(again.done) == list(range(written))
    again.append(_result(written))
    assert len(read_rows(store.path)) == written + 1


def test_a_failed_replacement_keeps_the_old_file_and_leaves_no_temporary(small_disk):
    disk, fill = small_disk
    target = disk / "summary.json"
    replace_durably(target, b'{"episodes": 3}\n')
    fill(leave=0)
    with pytest.raises(WriteError, match="No space left on device"):
        replace_durably(target, b"x" * 100_000)
    assert target.read_bytes() == b'{"episodes": 3}\n'
    assert sorted(p.name for p in disk.iterdir()) == ["filler", "summary.json"]


def test_create_new_never_overwrites(tmp_path):
    path = tmp_path / "layout.json"
    create_new(path, b"first")
    with pytest.raises(FileExistsError):
        create_new(path, b"second")
    assert path.read_bytes() == b"first" and [p.name for p in tmp_path.iterdir()] == [path.name]


def test_append_to_a_missing_file_is_a_write_error(tmp_path):
    with pytest.raises(WriteError, match="No such file"):
        append_durably(tmp_path / "gone.csv", b"row\n")


def _amex_run(args, cwd):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    return subprocess.run(
        [AMEX_RUN, *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=600
    )


@pytest.mark.slow
def test_amex_run_on_a_disk_that_fills_stops_with_one_line_and_resumes(small_disk, tmp_path):
    disk, fill = small_disk
    out = disk / "run"
    args = ["task=1", "method=track", "episodes=40", "max_time=0.3", f"hydra.run.dir={out}"]
    filler = fill(leave=5 * 4096)  # .hydra (3 pages), the lock and the first page of the csv
    proc = _amex_run(args, tmp_path)
    assert proc.returncode == 2, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert "No space left on device" in last and "episodes kept" in last and "resume" in last
    assert "Traceback" not in proc.stderr
    kept = read_rows(out / "episodes.csv")
    assert 0 < len(kept) < 40
    filler.unlink()
    proc = _amex_run(args, tmp_path)
    assert proc.returncode == 0, proc.stderr
    with open(out / "episodes.csv", newline="") as f:
        envs = [r["env"] for r in csv.DictReader(f)]
    assert envs == [str(i) for i in range(40)]  # nothing lost, nothing twice
