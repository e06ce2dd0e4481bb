"""A single run is composed once, and its run directory is the one ``hydra.main`` writes."""

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")

#: ``hydra.main`` on amex's job, as ``amex-run`` called it before it composed single runs once.
HYDRA_MAIN = """
import sys
import hydra
from amex.app.cli import flags_first
from amex.app.compose import CONF_DIR, register_schemas
from amex.app.job import task
register_schemas()
sys.argv[1:] = flags_first(sys.argv[2:])
hydra.main(CONF_DIR, config_name="config", version_base="1.3")(task)()
"""


def _env():
    env = dict(os.environ)
    env.pop("AMEX_DEBUG", None)
    return env


def _record(run_dir: Path, root: Path | None = None) -> dict:
    """The run's ``.hydra`` files, its directory (or ``root``, its sweep's) named ``RUN``."""
    record = {}
    for name in ("config.yaml", "hydra.yaml", "overrides.yaml"):
        text = (run_dir / ".hydra" / name).read_text().replace(str(root or run_dir), "RUN")
        record[name] = yaml.safe_load(text)
    return record


@pytest.mark.parametrize(
    "extra", [[], ["--config-dir", "{user}"], ["hydra.job.chdir=False", "hydra.verbose=true"]]
)
def test_single_run_writes_what_hydra_main_writes(tmp_path, extra):
    user = tmp_path / "user_conf"
    (user / "robot").mkdir(parents=True)
    extra = [a.replace("{user}", str(user)) for a in extra]
    args = ["task=1", "method=amex", "episodes=1", "max_time=0.3", *extra]
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    done = subprocess.run(
        [AMEX_RUN, *args, f"hydra.run.dir={ours}"],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    done = subprocess.run(
        [sys.executable, "-c", HYDRA_MAIN, "amex-run", *args, f"hydra.run.dir={theirs}"],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    assert _record(ours) == _record(theirs)
    assert (ours / "run.log").is_file()
    same = subprocess.run(
        [sys.executable, "-m", "analysis.same", str(ours), str(theirs)],
        cwd=Path(__file__).resolve().parents[2],
        capture_output=True,
        text=True,
    )
    assert same.returncode == 0, same.stdout + same.stderr


def test_a_single_run_composes_its_config_once(tmp_path, monkeypatch):
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    from amex.app import cli

    calls = []
    original = ConfigLoaderImpl.load_configuration

    def counted(self, *args, **kwargs):
        calls.append(kwargs.get("run_mode"))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(ConfigLoaderImpl, "load_configuration", counted)
    monkeypatch.chdir(tmp_path)
    run_dir = tmp_path / "run"
    argv = ["task=0", "method=track", "episodes=1", "max_time=0.01", f"hydra.run.dir={run_dir}"]
    monkeypatch.setattr(sys, "argv", ["amex-run", *argv])
    cli.run_main()
    assert len(calls) == 1, calls
    assert (run_dir / "episodes.csv").is_file() and (run_dir / ".hydra" / "hydra.yaml").is_file()


@pytest.mark.slow
def test_a_sweep_writes_what_hydra_main_writes(tmp_path):
    args = ["-m", "task=0", "method=track", "episodes=1", "max_time=0.01", "seed=0,1"]
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    for command, out in (
        ([AMEX_RUN], ours),
        ([sys.executable, "-c", HYDRA_MAIN, "amex-run"], theirs),
    ):
        done = subprocess.run(
            [*command, *args, f"hydra.sweep.dir={out}"],
            cwd=tmp_path,
            env=_env(),
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, done.stderr
    multirun = [
        yaml.safe_load((d / "multirun.yaml").read_text().replace(str(d), "SWEEP"))
        for d in (ours, theirs)
    ]
    assert multirun[0] == multirun[1]
    jobs = sorted(p.name for p in ours.iterdir() if p.is_dir())
    assert len(jobs) == 2 and jobs == sorted(p.name for p in theirs.iterdir() if p.is_dir())
    for job in jobs:
        assert _record(ours / job, ours) == _record(theirs / job, theirs), job
