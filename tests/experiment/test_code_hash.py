"""The configuration hash covers the code: a resume after a code change is refused with one line."""

import csv
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import amex
from amex.experiment.hashes import NOT_RESULT_CODE, source_digest

ROOT = Path(__file__).resolve().parents[2]
AMEX_RUN = str(Path(sys.executable).parent / "amex-run")
digest = source_digest.__wrapped__  # uncached: the test edits a tree after hashing it


@pytest.fixture
def tree(tmp_path):
    """A copy of amex's Python sources."""
    copy = tmp_path / "amex"
    shutil.copytree(Path(amex.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    return copy


@pytest.mark.parametrize(
    ("edited", "counts"),
    [
        ("methods/dmp.py", True),
        ("methods/original/cr.py", True),
        ("sim/episode.py", True),
        ("control/osc.py", True),
        ("plan/optimizer.py", True),
        ("experiment/config.py", True),
        ("app/cli.py", False),
        ("log/writer.py", False),
        ("experiment/store.py", False),
        ("core/durable.py", False),
    ],
)
def test_the_code_digest_covers_what_computes_results_and_not_the_rest(tree, edited, counts):
    before = digest(tree, NOT_RESULT_CODE)
    with open(tree / edited, "a") as f:
        f.write("\n# edited\n")
    assert (digest(tree, NOT_RESULT_CODE) != before) is counts


def _site_with_servo(tmp_path: Path) -> Path:
    """A directory that, on PYTHONPATH, looks like ``examples/amex_servo`` installed."""
    site = tmp_path / "site"
    info = site / "amex_servo-0.1.0.dist-info"
    info.mkdir(parents=True)
    shutil.copy(ROOT / "examples" / "amex_servo" / "amex_servo.py", site)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: amex-servo\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[amex.methods]\nservo = amex_servo:Servo\n")
    return site


def _run(args, cwd, site):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    env["PYTHONPATH"] = os.pathsep.join([str(site), *filter(None, [env.get("PYTHONPATH")])])
    return subprocess.run(
        [AMEX_RUN, *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=600
    )


@pytest.mark.slow
@pytest.mark.parametrize("change", ["module", "version"])
def test_a_resume_after_a_plugin_method_changed_is_refused_with_one_line(tmp_path, change):
    site = _site_with_servo(tmp_path)
    out = tmp_path / "run"
    args = ["task=1", "method=servo", "max_time=0.3", f"hydra.run.dir={out}"]
    first = _run([*args, "episodes=1"], tmp_path, site)
    assert first.returncode == 0, first.stderr
    recorded = (out / "episodes.csv").read_bytes()
    if change == "module":  # an edit of the method's code, a line that changes nothing else
        with open(site / "amex_servo.py", "a") as f:
            f.write("\nEDITED = True\n")
    else:
        meta = site / "amex_servo-0.1.0.dist-info" / "METADATA"
        meta.write_text(meta.read_text().replace("0.1.0", "0.1.1"))
    again = _run([*args, "episodes=2"], tmp_path, site)
    assert again.returncode == 2, again.stderr
    lines = again.stderr.strip().splitlines()
    assert len(lines) == 1 and "episodes.csv:2: episodes computed by other code" in lines[0]
    assert "method servo" in lines[0] and "Traceback" not in again.stderr
    assert (out / "episodes.csv").read_bytes() == recorded
    with open(out / "episodes.csv", newline="") as f:
        assert [r["env"] for r in csv.DictReader(f)] == ["0"]
