"""Fault injection, run directories: links to elsewhere refused, runs started together apart."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from amex.app.checks import OWN_FILES, validate_command_line
from amex.core.errors import UsageError

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


@pytest.mark.parametrize("name", [n for n in OWN_FILES if n != ".amex-run.lock"])
def test_a_run_directory_whose_own_file_is_a_link_is_refused_and_the_target_kept(tmp_path, name):
    run = tmp_path / "run"
    link = run / name
    link.parent.mkdir(parents=True, exist_ok=True)
    target = tmp_path / "precious.txt"
    target.write_text("the user's file")
    os.symlink(target, link)
    with pytest.raises(UsageError, match=rf"{name} is a symbolic link"):
        validate_command_line(["task=0", "method=track", "episodes=1", f"hydra.run.dir={run}"])
    assert target.read_text() == "the user's file"


@pytest.mark.slow
def test_runs_started_in_the_same_second_with_other_seeds_get_their_own_directories(tmp_path):
    procs = [
        subprocess.Popen(
            [AMEX_RUN, "task=0", "method=track", "episodes=1", "max_time=0.1", f"seed={seed}"],
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for seed in (1, 2, 3)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0], [err[-500:] for _, err in outs]
    dirs = {out.strip().splitlines()[-1] for out, _ in outs}
    assert len(dirs) == 3
    for directory in dirs:
        seed = directory.rsplit("_seed", 1)[1]
        overrides = (tmp_path / directory / ".hydra" / "overrides.yaml").read_text()
        assert f"seed={seed}" in overrides  # each records its own seed


@pytest.mark.slow
def test_of_two_runs_started_together_into_one_directory_the_record_is_the_winners(tmp_path):
    """The loser is refused before its Hydra writes a byte: .hydra/ records the winner's run."""
    for attempt in range(2):
        out = tmp_path / f"run{attempt}"
        procs = {
            seed: subprocess.Popen(
                [AMEX_RUN, "task=0", "method=track", "episodes=2", "max_time=0.3",
                 f"seed={seed}", f"hydra.run.dir={out}"],  # fmt: skip
                cwd=tmp_path,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            for seed in (1, 2)
        }
        codes = {seed: p.wait(timeout=300) for seed, p in procs.items()}
        for p in procs.values():
            p.communicate()
        winners = [seed for seed, code in codes.items() if code == 0]
        assert len(winners) == 1 and sorted(codes.values()) == [0, 2], codes
        overrides = (out / ".hydra" / "overrides.yaml").read_text()
        assert f"seed={winners[0]}" in overrides, overrides
