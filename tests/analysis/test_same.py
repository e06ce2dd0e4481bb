"""``python -m analysis.same``: two runs compared row by row, outside the timing columns."""

import csv
import shutil
from pathlib import Path

from analysis.same import main

RUNS = Path(__file__).resolve().parents[2] / "docs" / "data" / "runs" / "paper"


def _copy(tmp_path: Path, name: str) -> Path:
    out = tmp_path / name
    shutil.copytree(RUNS / "task1_amex_seed0", out / "task1_amex_seed0")
    return out


def _edit(run: Path, column: str, value: str, row: int = 3) -> None:
    path = run / "task1_amex_seed0" / "episodes.csv"
    rows = list(csv.DictReader(path.open()))
    rows[row][column] = value
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def test_a_run_is_the_same_as_its_copy_and_timing_columns_do_not_count(tmp_path, capsys):
    a, b = _copy(tmp_path, "a"), _copy(tmp_path, "b")
    _edit(b, "compute_time_median", "0.5")  # a slower machine: no difference
    assert main([str(a), str(b)]) == 0
    assert "1 cells, 150 rows compared: 0 rows differ" in capsys.readouterr().out


def test_one_changed_result_is_found_and_named(tmp_path, capsys):
    a, b = _copy(tmp_path, "a"), _copy(tmp_path, "b")
    value = float(
        next(csv.DictReader((a / "task1_amex_seed0" / "episodes.csv").open()))["final_time"]
    )
    _edit(b, "final_time", repr(value + 1e-9), row=0)
    assert main([str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert (
        "final_time: 1 rows differ" in out and ": 1 rows differ outside the timing columns" in out
    )


def test_a_missing_directory_is_one_line_and_exit_2(tmp_path, capsys):
    assert main([str(tmp_path / "nothing"), str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
