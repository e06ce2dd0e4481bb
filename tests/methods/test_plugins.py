"""Methods from other packages: the ``amex.methods`` entry points, end to end."""

import csv
import os
import shutil
import subprocess
import sys
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

import amex.methods as registry

ROOT = Path(__file__).resolve().parents[2]
AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


def _site_with_servo(tmp_path: Path) -> Path:
    """A directory that, on PYTHONPATH, looks like ``examples/amex_servo`` installed."""
    site = tmp_path / "site"
    info = site / "amex_servo-0.1.0.dist-info"
    info.mkdir(parents=True)
    shutil.copy(ROOT / "examples" / "amex_servo" / "amex_servo.py", site)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: amex-servo\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[amex.methods]\nservo = amex_servo:Servo\n")
    return site


@pytest.mark.slow
def test_a_plugin_method_runs_from_the_command_line_beside_the_built_ins(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    env["PYTHONPATH"] = str(_site_with_servo(tmp_path))
    run_dir = tmp_path / "run"
    args = ["task=1", "method=servo", "method.speed=0.15", "episodes=2", f"hydra.run.dir={run_dir}"]
    done = subprocess.run(
        [AMEX_RUN, *args], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stderr
    with open(run_dir / "episodes.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(r["method"], r["env"]) for r in rows] == [("servo", "0"), ("servo", "1")]
    assert all(r["failure"] == "" and float(r["final_distance"]) < 0.03 for r in rows)
    bad = subprocess.run(
        [AMEX_RUN, "method=nope", f"hydra.run.dir={tmp_path / 'bad'}"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
    )
    assert bad.returncode == 2 and "servo" in bad.stderr and "amex" in bad.stderr
    slow = subprocess.run(  # the plugin's own validate(), before anything is written
        [AMEX_RUN, "method=servo", "method.speed=0", f"hydra.run.dir={tmp_path / 'slow'}"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
    )
    assert slow.returncode == 2 and "method.speed=0" in slow.stderr, slow.stderr
    assert len(slow.stderr.strip().splitlines()) == 1 and not (tmp_path / "slow").exists()


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("broken", "amex_no_such_module_xyz:Thing", "failed to import"),
        ("amex", "amex.methods.track:Track", "the name is taken"),
        ("other", "amex.methods.track:Track", "class's name is 'track'"),
        ("notamethod", "amex.experiment.config:RunConfig", "not a subclass"),
    ],
)
def test_a_plugin_that_does_not_fit_is_skipped_with_a_warning(monkeypatch, name, value, reason):
    before = dict(registry.METHODS)
    ep = EntryPoint(name=name, value=value, group=registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry, "entry_points", lambda group: [ep])
    with pytest.warns(RuntimeWarning, match=f"method plugin {name} = .*skipped: .*{reason}"):
        assert registry.load_plugins() == []
    assert before == registry.METHODS
