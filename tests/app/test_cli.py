"""End-to-end tests of ``amex-run``: real Hydra, real MuJoCo, small episode counts."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from amex.experiment.store import CSV_COLUMNS
from amex.sim.metrics import TIMING_COLUMNS

AMEX_RUN = str(Path(sys.executable).parent / "amex-run")


def _run(args, cwd):
    env = dict(os.environ)
    env.pop("AMEX_DEBUG", None)
    return subprocess.run(
        [AMEX_RUN, *args], cwd=cwd, capture_output=True, text=True, env=env, timeout=600
    )


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["task=9"], "task=9"),
        (["task=abc"], "task='abc'"),
        (["method=nope"], "method='nope'"),
        (["episodes=0"], "episodes=0"),
        (["seed=-1"], "seed=-1"),
        (["inner_hz=150", "outer_hz=100"], "inner_hz=150"),
        (["max_time=-1"], "max_time=-1"),
        (["foo=1"], "'foo'"),
        (["log=full", "log_compression=gzip"], "log_compression='gzip'"),
        (["-m", "task=1,7"], "task=7"),
    ],
)
def test_bad_input_gets_one_line_exit_2_and_no_run_directory(tmp_path, args, needle):
    proc = _run(args, tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert needle in lines[0] and "valid" in lines[0]
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "runs").exists() and not (tmp_path / "outputs").exists()


def _read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_run_writes_episodes_and_summary_and_prints_the_directory(tmp_path):
    out = tmp_path / "run"
    proc = _run(
        ["task=0", "method=track", "episodes=2", "seed=3", f"hydra.run.dir={out}"], tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == str(out)
    rows = _read_rows(out / "episodes.csv")
    assert tuple(rows[0].keys()) == CSV_COLUMNS
    assert [r["env"] for r in rows] == ["0", "1"]
    assert all(r["success"] == "1" and r["seed"] == "3" for r in rows)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["episodes"] == 2 and summary["success"]["mean"] == 1.0


def test_same_config_and_seed_give_identical_episodes_bit_for_bit(tmp_path):
    tables = []
    for name in ("a", "b"):
        out = tmp_path / name
        proc = _run(
            ["task=2", "method=track", "episodes=2", "seed=5", f"hydra.run.dir={out}"], tmp_path
        )
        assert proc.returncode == 0, proc.stderr
        rows = _read_rows(out / "episodes.csv")
        tables.append([{k: v for k, v in r.items() if k not in TIMING_COLUMNS} for r in rows])
    assert tables[0] == tables[1]


def test_multirun_sweeps_tasks(tmp_path):
    sweep = tmp_path / "sweep"
    proc = _run(
        ["-m", "task=0,1", "method=track", "episodes=1", "max_time=2", f"hydra.sweep.dir={sweep}"],
        tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    csvs = sorted(sweep.glob("*/episodes.csv"))
    assert len(csvs) == 2
    assert {_read_rows(p)[0]["task"] for p in csvs} == {"0", "1"}


def test_rerun_resumes_and_keeps_recorded_episodes(tmp_path):
    out = tmp_path / "run"
    args = ["task=1", "method=track", "seed=2", "max_time=1", f"hydra.run.dir={out}"]
    assert _run([*args, "episodes=2"], tmp_path).returncode == 0
    first = (out / "episodes.csv").read_text()
    # simulate a crash that tore the last line
    with open(out / "episodes.csv", "a") as f:
        f.write("1,track,2,2,0,0")
    proc = _run([*args, "episodes=3"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    after = (out / "episodes.csv").read_text()
    assert after.startswith(first)  # recorded rows untouched, torn line dropped
    assert [r["env"] for r in _read_rows(out / "episodes.csv")] == ["0", "1", "2"]


def test_run_directory_of_another_config_is_refused_untouched(tmp_path):
    out = tmp_path / "run"
    base = ["task=0", "method=track", "episodes=1", "max_time=1", f"hydra.run.dir={out}"]
    assert _run([*base, "seed=1"], tmp_path).returncode == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    proc = _run([*base, "seed=2"], tmp_path)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "another configuration" in proc.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_submitit_local_launcher_runs_a_sweep(tmp_path):
    sweep = tmp_path / "sweep"
    proc = _run(
        [
            "-m",
            "hydra/launcher=submitit_local",
            "task=0,1",
            "method=track",
            "episodes=1",
            "max_time=1",
            f"hydra.sweep.dir={sweep}",
        ],
        tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert len(list(sweep.glob("*/episodes.csv"))) == 2


def test_slurm_launcher_config_composes(tmp_path):
    proc = _run(["hydra/launcher=slurm", "--cfg", "hydra"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "SlurmLauncher" in proc.stdout and "cpus_per_task: 1" in proc.stdout


def test_help_lists_tasks_methods_robots_experiments_options_and_outputs(tmp_path):
    proc = _run(["--help"], tmp_path)
    assert proc.returncode == 0 and not proc.stderr
    out = proc.stdout
    conf = Path(__file__).resolve().parents[2] / "conf"
    for section in ("tasks (task=N)", "methods (method=NAME", "robots (robot=NAME",
                    "experiments (experiment=NAME", "main options", "outputs:"):  # fmt: skip
        assert section in out
    methods = out.split("methods (")[1].split("\n\n")[0]
    assert "schema_" not in methods and "  dmp_ps  " in methods
    for yaml_file in conf.glob("robot/*.yaml"):
        assert f"  {yaml_file.stem}  " in out  # discovered from the files
    for yaml_file in (conf / "experiment").rglob("*.yaml"):
        name = yaml_file.relative_to(conf / "experiment").with_suffix("").as_posix()
        assert f"  {name}  " in out
    assert "outer_hz=100.0" in out and "[Hz]" in out and "max_time=10.0" in out
    assert "episodes.csv" in out and "hydra.run.dir=DIR" in out
    assert not list(tmp_path.iterdir())  # no run directory


def test_a_schema_is_not_a_method(tmp_path):
    proc = _run(["method=schema_amex"], tmp_path)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "invalid method='schema_amex'; valid: amex, " in proc.stderr
    valid = proc.stderr.split("valid: ")[1].strip().split(", ")
    assert "cr" in valid and not any(name.startswith("schema_") for name in valid)
    assert not (tmp_path / "runs").exists()


def test_resumed_run_says_what_it_kept_and_run_log_records_the_episodes(tmp_path):
    args = ["task=0", "method=dmp", "hydra.run.dir=out"]
    first = _run([*args, "episodes=2"], tmp_path)
    assert first.returncode == 0, first.stderr
    assert "resuming" not in first.stderr and "success=2/2" in first.stderr
    second = _run([*args, "episodes=3"], tmp_path)
    assert second.returncode == 0, second.stderr
    assert f"resuming {tmp_path / 'out'}: kept 2 of 3 episodes recorded earlier, running the " \
        "other 1" in second.stderr
    assert "success=3/3" in second.stderr  # counts the kept episodes too
    assert "[INFO]" not in second.stderr  # the record goes to run.log, not the terminal
    log = (tmp_path / "out" / "run.log").read_text()
    assert "2 recorded earlier, 1 to run" in log and "env 2: success" in log
    assert "done: success 1.000" in log
    assert not (tmp_path / "out" / "cli.log").exists()
