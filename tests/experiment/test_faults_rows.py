"""Fault injection, episodes.csv rows: every bad row is refused alike by resume and table; nothing
a run does not own is dropped."""

import csv
import io
import os

import pytest

from amex.core.errors import StoreError
from amex.experiment.config import RunConfig
from amex.experiment.runner import run
from amex.experiment.store import EpisodeStore, read_episodes, read_rows, row_checksum
from amex.methods import METHODS
from analysis.table import load_runs


def _config(episodes: int, **changes) -> RunConfig:
    config = RunConfig(task=0, episodes=episodes, max_time=0.2, **changes)
    config.method = METHODS["track"].config_class()
    return config


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A run directory with 3 recorded episodes, and one of another seed."""
    base = tmp_path_factory.mktemp("recorded")
    run(_config(3), base / "run")
    run(_config(2, seed=1), base / "other")
    return base


def _table(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def _write(path, header, rows):
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows([header, *rows])
    path.write_text(buf.getvalue())


def _rehash(header, row):
    """The row with its row_hash recomputed, as a forger who read the code would."""
    row = list(row)
    row[header.index("row_hash")] = row_checksum(header, row)
    return row


def _copy(recorded, tmp_path):
    out = tmp_path / "runs" / "run"
    out.mkdir(parents=True)
    (out / "episodes.csv").write_bytes((recorded / "run" / "episodes.csv").read_bytes())
    return out / "episodes.csv"


def _damage(kind, path, recorded):
    header, rows = _table(path)
    col = header.index
    if kind == "duplicate_env":
        rows.append(rows[0])
    elif kind == "edited_value":
        rows[1][col("final_distance")] = "0.001"
    elif kind == "forged_config_hash":  # another configuration's rows passed off as this one's
        other_header, other = _table(recorded / "other" / "episodes.csv")
        row = other[1]
        row[col("config_hash")] = rows[0][col("config_hash")]
        rows.append(row)
    elif kind == "env_beyond_the_run":
        rows.append(_rehash(header, [*rows[2][: col("env")], "999", *rows[2][col("env") + 1 :]]))
    elif kind == "not_finite":
        rows[1][col("final_time")] = "inf"
        rows[1] = _rehash(header, rows[1])
    elif kind == "negative":
        rows[1][col("sum_sq_acc")] = "-1.0"
        rows[1] = _rehash(header, rows[1])
    elif kind == "edited_method":
        rows[1][col("method")] = "amex"
        rows[1] = _rehash(header, rows[1])
    elif kind == "two_configurations":
        rows += _table(recorded / "other" / "episodes.csv")[1]
    elif kind == "blanked_row_hash":
        rows[1][col("final_distance")] = "0.001"
        rows[1][col("row_hash")] = ""
    _write(path, header, rows)


DAMAGE = {
    "duplicate_env": r":5: env 0 recorded twice \(first on line 2\)",
    "edited_value": r":3: row_hash \w+ does not match the row's values",
    "forged_config_hash": r":5: row_hash \w+ does not match",
    "env_beyond_the_run": r":5: env=999 beyond the run's 3 episodes",
    "not_finite": r":3: impossible value: final_time=inf",
    "negative": r":3: impossible value: sum_sq_acc=-1.0",
    "edited_method": r":3: rows of two configurations in one file: method=amex here, track on",
    "two_configurations": r":5: rows of two configurations in one file: seed=1 here, 0 on line 2",
    "blanked_row_hash": r":3: row_hash is empty where the rows before carry one",
}


@pytest.mark.parametrize("kind", DAMAGE)
def test_a_bad_row_is_refused_alike_by_resume_and_table_with_file_and_line(
    recorded, tmp_path, kind
):
    path = _copy(recorded, tmp_path)
    _damage(kind, path, recorded)
    before = path.read_bytes()
    problem = rf"episodes.csv{DAMAGE[kind]}"
    with pytest.raises(StoreError, match=problem):
        read_rows(path)
    with pytest.raises(StoreError, match=problem):
        load_runs(tmp_path / "runs")
    with pytest.raises(StoreError, match=problem):
        EpisodeStore.for_config(path, _config(3))
    with pytest.raises(StoreError, match=problem):
        run(_config(3), path.parent)
    assert path.read_bytes() == before  # refused untouched


def test_rows_of_a_file_without_row_hashes_read_flagged_unverified_but_do_not_resume(
    recorded, tmp_path
):
    path = _copy(recorded, tmp_path)
    header, rows = _table(path)
    k = header.index("row_hash")
    _write(path, header[:k], [r[:k] for r in rows])  # as an amex before row hashes wrote it
    stored = read_episodes(path)
    assert not stored.verified and [r.env for r in stored.results] == [0, 1, 2]
    assert read_episodes(recorded / "run" / "episodes.csv").verified
    assert len(load_runs(tmp_path / "runs")) == 3
    with pytest.raises(StoreError, match=r"episodes.csv:2: no row_hash: the row cannot be"):
        EpisodeStore.for_config(path, _config(3))


def test_a_resume_never_rewrites_a_file_with_rows(recorded, tmp_path):
    path = _copy(recorded, tmp_path)
    before, inode = path.read_bytes(), os.stat(path).st_ino
    run(_config(3), path.parent)  # nothing left to run
    assert path.read_bytes() == before and os.stat(path).st_ino == inode
    run(_config(4), path.parent)  # one more row, appended
    assert path.read_bytes().startswith(before) and os.stat(path).st_ino == inode


@pytest.mark.parametrize("where", ["after_row_hash", "newer_metric"])
def test_columns_amex_does_not_know_are_kept_and_left_empty_in_new_rows(recorded, tmp_path, where):
    path = _copy(recorded, tmp_path)
    header, rows = _table(path)
    if where == "after_row_hash":  # a user's note, after the checksummed columns
        header = [*header, "note"]
        rows = [[*r, f"looked at {i}"] for i, r in enumerate(rows)]
    else:  # a metric a newer amex added among its columns, its rows hashed by that version
        k = header.index("config_hash")
        header = [*header[:k], "newer_metric", *header[k:]]
        rows = [_rehash(header, [*r[:k], "0.5", *r[k:]]) for r in rows]
    _write(path, header, rows)
    before = path.read_bytes()
    run(_config(4), path.parent)
    assert path.read_bytes().startswith(before)  # nothing of it rewritten
    stored = read_episodes(path)
    assert stored.header == tuple(header) and stored.verified
    column = header[-1] if where == "after_row_hash" else "newer_metric"
    assert [r[column] for r in stored.rows][:3] == [r[header.index(column)] for r in rows]
    assert stored.rows[3][column] == "" and stored.rows[3]["env"] == "3"
    assert len(load_runs(tmp_path / "runs")) == 4


def test_a_file_with_a_header_and_no_rows_gets_this_versions_columns(tmp_path):
    from amex.experiment.store import CSV_COLUMNS
    from amex.sim.metrics import COLUMNS

    path = tmp_path / "run" / "episodes.csv"
    path.parent.mkdir()
    _write(path, [*COLUMNS, "config_hash", "scene_hash", "note"], [])  # older amex, no rows
    run(_config(1), path.parent)
    stored = read_episodes(path)
    assert stored.header == (*CSV_COLUMNS, "note")  # an unknown column's name is kept
    assert stored.verified and [r["env"] for r in stored.rows] == ["0"]
