"""Fault injection, symbolic links planted in a run directory: refused, never written through."""

import os

import pytest

from amex.core.durable import LOCK_NAME, RunLock, append_durably, create_new, replace_durably
from amex.core.errors import WriteError
from amex.experiment.config import RunConfig
from amex.experiment.runner import run
from amex.methods import METHODS

PRECIOUS = b"someone else's file\n"


@pytest.fixture
def victim(tmp_path):
    """A file outside the run directory that a planted link points at."""
    path = tmp_path / "elsewhere" / "precious.txt"
    path.parent.mkdir()
    path.write_bytes(PRECIOUS)
    return path


def _link(directory, name, target):
    directory.mkdir(exist_ok=True)
    link = directory / name
    link.symlink_to(target)
    return link


def test_a_symlinked_lock_file_is_refused_and_its_target_left_alone(tmp_path, victim):
    run_dir = tmp_path / "run"
    link = _link(run_dir, LOCK_NAME, victim)
    with pytest.raises(WriteError, match=rf"{LOCK_NAME}: it is a symbolic link \(to {victim}\)"):
        RunLock(run_dir).acquire()
    assert victim.read_bytes() == PRECIOUS and link.is_symlink()
    assert RunLock.holder(run_dir) is None  # a link is nobody's lock


def test_a_dangling_lock_link_creates_nothing(tmp_path):
    run_dir = tmp_path / "run"
    target = tmp_path / "would_be_created"
    _link(run_dir, LOCK_NAME, target)
    with pytest.raises(WriteError, match="symbolic link"):
        RunLock(run_dir).acquire()
    assert not target.exists()


def test_a_lock_path_that_is_not_a_regular_file_is_refused(tmp_path):
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    os.mkfifo(run_dir / LOCK_NAME)
    with pytest.raises(WriteError, match="not a regular file"):
        RunLock(run_dir).acquire()


@pytest.mark.parametrize("write", ["append", "replace", "create"])
def test_no_durable_write_follows_a_symlink(tmp_path, victim, write):
    link = _link(tmp_path / "run", "episodes.csv", victim)
    expected = FileExistsError if write == "create" else WriteError
    with pytest.raises(expected, match="symbolic link|file exists"):
        {"append": append_durably, "replace": replace_durably, "create": create_new}[write](
            link, b"overwritten\n"
        )
    assert victim.read_bytes() == PRECIOUS and link.is_symlink()
    assert sorted(p.name for p in link.parent.iterdir()) == ["episodes.csv"]  # no temporary


def test_a_run_into_a_directory_with_planted_links_writes_through_none(tmp_path, victim):
    config = RunConfig(task=0, episodes=1, max_time=0.2)
    config.method = METHODS["track"].config_class()
    run_dir = tmp_path / "run"
    for name in ("episodes.csv", LOCK_NAME):
        run_dir.mkdir(exist_ok=True)
        for p in run_dir.iterdir():
            p.unlink()
        _link(run_dir, name, victim)
        with pytest.raises(WriteError, match=rf"{name}: it is a symbolic link"):
            run(config, run_dir)
        assert victim.read_bytes() == PRECIOUS
