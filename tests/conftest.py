"""Shared fixtures: the real robot, and a per-session plan cache in a temporary directory."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("OMP_NUM_THREADS", "1")


@pytest.fixture(scope="session", autouse=True)
def _plan_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Keep test runs from reading or writing the user's plan cache."""
    if "AMEX_CACHE_DIR" not in os.environ:
        os.environ["AMEX_CACHE_DIR"] = str(tmp_path_factory.mktemp("amex_cache"))


@pytest.fixture(scope="session")
def robot():
    from amex.robot import load_robot

    return load_robot()


@pytest.fixture
def small_disk(tmp_path):
    """A real 256 KiB file system (tmpfs) that can fill up; skipped where mounting is not allowed.

    Yields ``(mount_point, fill)``: ``fill(leave)`` writes a filler file leaving ``leave`` bytes
    free and returns it (delete it to free the space again).
    """
    import shutil
    import subprocess

    mount_point = tmp_path / "disk"
    mount_point.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mount_point)],
        capture_output=True,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")

    def fill(leave: int):
        filler = mount_point / "filler"
        free = os.statvfs(mount_point).f_bavail * os.statvfs(mount_point).f_frsize
        with open(filler, "ab") as f:
            f.write(b"\0" * max(free - leave, 0))
        return filler

    try:
        yield mount_point, fill
    finally:
        subprocess.run(["umount", "-l", str(mount_point)], capture_output=True)


@pytest.fixture
def read_only_dir(tmp_path):
    """A directory nobody can write into: read-only for non-root users, else a read-only tmpfs."""
    import subprocess

    path = tmp_path / "read_only"
    path.mkdir()
    if os.geteuid() != 0:
        path.chmod(0o555)
        yield path
        path.chmod(0o755)
        return
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(path)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a read-only tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)
