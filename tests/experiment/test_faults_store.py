"""Fault injection, stored results: hand-edited or empty csv files and summaries that could lie."""

import csv
import json

import pytest

from amex.app.checks import validate_command_line
from amex.core.errors import StoreError, UsageError, WriteError
from amex.experiment.config import RunConfig
from amex.experiment.runner import run
from amex.experiment.store import CSV_COLUMNS, EpisodeStore, config_hash, read_rows, scene_hash
from amex.methods import METHODS
from analysis.table import TableError, load_runs


def _config(episodes: int, **changes) -> RunConfig:
    config = RunConfig(task=0, episodes=episodes, max_time=0.2, **changes)
    config.method = METHODS["track"].config_class()
    return config


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A run directory with 3 recorded episodes."""
    out = tmp_path_factory.mktemp("recorded") / "run"
    run(_config(3), out)
    return out


def _copy(recorded, tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    (out / "episodes.csv").write_bytes((recorded / "episodes.csv").read_bytes())
    return out


def _edit(path, column, value, row=1):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    rows[row][column] = value
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def test_a_zero_byte_episodes_csv_is_a_fresh_run(tmp_path, monkeypatch):
    out = tmp_path / "run"
    out.mkdir()
    (out / "episodes.csv").write_bytes(b"")
    assert read_rows(out / "episodes.csv") == []
    monkeypatch.chdir(tmp_path)
    validate_command_line(["task=0", "method=track", "episodes=2", f"hydra.run.dir={out}"])
    run(_config(2), out)
    assert [r["env"] for r in read_rows(out / "episodes.csv")] == ["0", "1"]


@pytest.mark.parametrize(
    ("column", "value"),
    [("success", "2"), ("success", "yes"), ("success", ""), ("collided", "true"), ("env", "x")],
)
def test_a_bad_stored_value_is_refused_alike_by_resume_and_by_the_table(
    recorded, tmp_path, monkeypatch, column, value
):
    out = _copy(recorded, tmp_path)
    _edit(out / "episodes.csv", column, value)
    config = _config(3)
    with pytest.raises(StoreError, match=rf"episodes.csv:3: malformed row .*{column}="):
        EpisodeStore(out / "episodes.csv", config_hash(config), scene_hash(config))
    with pytest.raises(StoreError, match=rf"episodes.csv:3: malformed row .*{column}="):
        load_runs(tmp_path)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UsageError, match="malformed row"):
        validate_command_line(["task=0", "method=track", "episodes=3", f"hydra.run.dir={out}"])


def test_resume_and_table_read_the_same_values(recorded):
    store_rows = read_rows(recorded / "episodes.csv")
    resumed = EpisodeStore(recorded / "episodes.csv", store_rows[0]["config_hash"], "")
    table = load_runs(recorded.parent)
    for env, result in resumed.done.items():
        row = table[table.env == env].iloc[0]
        assert bool(row.success) is result.success and bool(row.collided) is result.collided
        assert row.final_time == result.final_time


def test_a_shorter_rerun_writes_a_summary_of_what_it_asked_for(recorded, tmp_path):
    out = _copy(recorded, tmp_path)
    summary = run(_config(2), out)
    written = json.loads((out / "summary.json").read_text())
    assert written == json.loads(json.dumps(summary))
    assert written["episodes"] == 2 and written["recorded"] == 3


def test_a_run_that_fails_leaves_no_summary_of_an_earlier_run(recorded, tmp_path, monkeypatch):
    out = _copy(recorded, tmp_path)
    run(_config(3), out)
    assert json.loads((out / "summary.json").read_text())["episodes"] == 3

    def full_disk(path, data):
        raise WriteError(path, "No space left on device")

    monkeypatch.setattr("amex.experiment.runner.replace_durably", full_disk)
    with pytest.raises(WriteError):
        run(_config(2), out)
    assert not (out / "summary.json").exists()  # no stale count left to be believed


def test_every_csv_empty_is_a_table_error_not_a_crash(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "episodes.csv").write_bytes(b"")
    with pytest.raises(TableError, match="empty"):
        load_runs(tmp_path)
