"""amex as a user installs it: the wheel in a fresh venv, used from a directory of one's own.

Slow (a fresh venv takes ~1-2 min to install): ``make test-slow`` runs it, and CI.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


def _run(args, cwd, env, timeout=900):
    done = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, (
        f"{' '.join(map(str, args))}\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    )
    return done


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """A fresh venv with amex's wheel and the example project's method installed."""
    base = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    source = base / "source"  # what a clone holds: the tracked files, no build/ left from before
    files = _run(["git", "ls-files", "-z"], ROOT, env).stdout.split("\0")
    for name in filter(None, files):
        if (ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, source / name)
    wheel_dir = base / "dist"
    pip_wheel = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q"]
    _run([*pip_wheel, source, "-w", wheel_dir], base, env)
    (wheel,) = (base / "dist").glob("amex-*.whl")
    _run([sys.executable, "-m", "venv", base / "venv"], base, env)
    pip = base / "venv" / "bin" / "pip"
    plugin = ROOT / "examples" / "my_project" / "my_methods"
    _run([pip, "install", "-q", wheel, plugin], base, env, timeout=1800)
    project = base / "my_project"
    shutil.copytree(ROOT / "examples" / "my_project", project)
    env = {
        **env,
        "AMEX_CACHE_DIR": str(base / "cache"),
        "PATH": f"{base / 'venv' / 'bin'}:{env['PATH']}",
    }
    return base / "venv" / "bin", project, env


def test_the_wheel_ships_its_configs_and_runs_an_episode_from_anywhere(installed, tmp_path):
    bin_dir, _, env = installed
    run = _run([bin_dir / "amex-run", "task=0", "method=amex", "episodes=2", "max_time=1",
                "hydra.run.dir=one"], tmp_path, env)  # fmt: skip
    assert (tmp_path / "one" / "episodes.csv").is_file() and "one" in run.stdout
    sweep = _run([bin_dir / "amex-run", "-m", "task=0", "method=amex,track", "episodes=1",
                  "max_time=0.5", "hydra.sweep.dir=sweep"], tmp_path, env)  # fmt: skip
    assert "sweep sweep: 2 jobs" in sweep.stderr.replace(str(tmp_path) + "/", "")
    assert len(list((tmp_path / "sweep").glob("*/episodes.csv"))) == 2
    table = _run([bin_dir / "amex-analysis", "table", "sweep"], tmp_path, env)
    assert (tmp_path / "analysis" / "out" / "fig5.md").is_file(), table.stdout
    help_text = _run([bin_dir / "amex-run", "--help"], tmp_path, env).stdout
    assert "ablation/1_harness" in help_text and "ur10" in help_text
    version = _run([bin_dir / "amex-run", "--version"], tmp_path, env).stdout
    import amex

    assert version.strip() == f"amex-run {amex.__version__}"
    site = next((bin_dir.parent / "lib").glob("python3*/site-packages"))
    assert (site / "amex" / "conf" / "config.yaml").is_file() and not (site / "analysis").exists()


def test_the_example_project_runs_its_experiment_robot_and_method(installed):
    bin_dir, project, env = installed
    help_text = _run([bin_dir / "amex-run", "--config-dir", "conf", "--help"], project, env).stdout
    assert "my_arm" in help_text and "my_reach" in help_text and "glide" in help_text
    _run([bin_dir / "amex-run", "--config-dir", "conf", "-m", "experiment=my_reach",
          "method=glide,amex", "episodes=3", "hydra.sweep.dir=runs/mine"], project, env)
    rows = {
        p.parent.name: p.read_text() for p in (project / "runs" / "mine").glob("*/episodes.csv")
    }
    assert sorted(rows) == ["task1_amex_seed0", "task1_glide_seed0"]
    assert all(text.count("\n") == 4 for text in rows.values())  # a header and 3 rows each
    config = (
        project / "runs" / "mine" / "task1_glide_seed0" / ".hydra" / "config.yaml"
    ).read_text()
    assert "name: my_arm" in config and "robots/my_arm.urdf" in config
    _run([bin_dir / "amex-analysis", "table", "runs/mine"], project, env)
    bad = subprocess.run([bin_dir / "amex-run", "--config-dir", "conf", "experiment=my_reach",
                          "method.approach_rate=-1"], cwd=project, env=env, capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1, bad.stderr


def test_the_python_api_example_runs_against_the_wheel(installed, tmp_path):
    bin_dir, _, env = installed
    _run([bin_dir / "python", ROOT / "examples" / "python_api.py", tmp_path / "out"], tmp_path, env)
    assert (tmp_path / "out" / "logs" / "episode_000.mcap").is_file()
    info = _run([bin_dir / "amex-log", "info", tmp_path / "out" / "logs" / "episode_000.mcap"],
                tmp_path, env)  # fmt: skip
    assert "outcome" in info.stdout
