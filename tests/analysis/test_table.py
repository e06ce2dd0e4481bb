"""``make table`` on real runs: the report, and clear errors that overwrite nothing."""

import shutil
from pathlib import Path

import pytest

from amex.experiment.config import RunConfig
from amex.experiment.runner import run
from amex.methods import METHODS
from analysis.table import main


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    for task in (1, 2):
        for name in ("amex", "dmp"):
            config = RunConfig(task=task, episodes=3, max_time=6.0)
            config.method = METHODS[name].config_class()
            run(config, root / f"task{task}_{name}")
    return root


def test_table_reports_ours_beside_the_paper_with_paired_stats(runs, tmp_path, capsys):
    assert main([str(runs), "--out", str(tmp_path)]) == 0
    md = (tmp_path / "fig5.md").read_text()
    assert "| 1 | amex | 3 |" in md and "4.17 ± 0.77" in md  # the paper's Task 1 AMEX row
    assert "## Paired comparisons" in md and "amex | dmp | final_time" in md
    assert "| 1 | amex | dmp | success | 3 | 0 | [0, 0] | mcnemar | 1 |" in md
    assert "AMEX is smoother than DMP" in md
    for name in ("fig5.tex", "fig5.csv", "paired.csv"):
        assert (tmp_path / name).stat().st_size > 0


def test_claims_judged_on_fewer_than_30_environments_are_inconclusive(runs, tmp_path):
    assert main([str(runs), "--out", str(tmp_path)]) == 0
    md = (tmp_path / "fig5.md").read_text()
    claims = md.split("## The paper's claims")[1].split("\n## ")[0]
    assert "| AMEX is smoother than DMP (exact) | inconclusive (n = 3 < 30) |" in claims
    assert "| holds" not in claims and "| fails" not in claims


def test_latex_is_two_booktabs_tables_for_a_column(runs, tmp_path):
    assert main([str(runs), "--out", str(tmp_path)]) == 0
    tex = (tmp_path / "fig5.tex").read_text()
    assert tex.count("\\begin{table}") == 2 and tex.count("\\toprule") == 2
    assert "tabular}{llccc}" in tex and "tabular}{llcccc}" in tex  # 5 and 6 columns
    assert "4.17\\,$\\pm$\\,0.77" in tex  # the paper's Task 1 AMEX final time


def test_fig5_figures_are_drawn_per_task_as_png_and_pdf(runs, tmp_path):
    from analysis.fig5 import plot_runs

    written = plot_runs(runs, tmp_path)
    names = {p.name for p in written}
    assert {"fig5.png", "fig5.pdf", "fig5_task1.png", "fig5_task2.pdf"} <= names
    assert (tmp_path / "fig5.png").stat().st_size > 50_000


def test_wilson_interval_contains_the_rate_and_stays_in_0_1():
    from analysis.fig5 import wilson

    assert wilson(10, 10)[1] == 1.0 and wilson(10, 10)[0] == pytest.approx(0.722, abs=1e-3)
    assert wilson(0, 5)[0] == 0.0
    lo, hi = wilson(7, 20)
    assert lo < 0.35 < hi


def test_table_runs_from_any_directory(runs, tmp_path):
    import subprocess
    import sys

    analysis = str(Path(sys.executable).parent / "amex-analysis")  # as installed
    proc = subprocess.run(
        [analysis, "table", str(runs), "--out", str(tmp_path / "out")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out" / "fig5.md").exists()
    proc = subprocess.run([analysis, "table", str(runs)], cwd=tmp_path, capture_output=True)
    assert proc.returncode == 0 and (tmp_path / "analysis" / "out" / "fig5.md").exists()


def _bad_input(tmp_path, capsys, root):
    out = tmp_path / "out"
    out.mkdir(exist_ok=True)
    (out / "fig5.md").write_text("previous table")
    code = main([str(root), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("make table: error:")
    assert (out / "fig5.md").read_text() == "previous table"
    return err[0]


def test_no_runs_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert "no episodes.csv" in _bad_input(tmp_path, capsys, tmp_path / "empty")


def test_corrupt_csv_names_the_file(runs, tmp_path, capsys):
    root = tmp_path / "copy"
    shutil.copytree(runs, root)
    bad = root / "task1_amex" / "episodes.csv"
    lines = bad.read_text().splitlines(keepends=True)
    bad.write_text(lines[0] + "1,amex,oops\n" + "".join(lines[1:]))
    assert str(bad) in _bad_input(tmp_path, capsys, root)


def test_each_benchmark_configuration_gets_its_own_table_and_an_index(runs, tmp_path, capsys):
    root = tmp_path / "mixed"
    shutil.copytree(runs, root)
    config = RunConfig(task=1, episodes=1, max_time=1.0, seed=9)
    config.method = METHODS["dmp"].config_class()
    run(config, root / "other_seed")
    out = tmp_path / "out"
    out.mkdir()
    (out / "fig5.tex").write_text("a table of an earlier call")
    assert main([str(root), "--out", str(out)]) == 0
    index = (out / "fig5.md").read_text()
    assert "2 benchmark configurations" in index
    tables = sorted(out.glob("scene_*/fig5.md"))
    assert len(tables) == 2
    assert any("| 1 | amex | 3 |" in table.read_text() for table in tables)
    assert not (out / "fig5.tex").exists()  # no stale single-configuration table
    assert "2 benchmark configurations" in capsys.readouterr().out


def test_duration_invariant_smoothness_is_unchanged_by_slowing_a_motion_down():
    import numpy as np

    from analysis.episodes import duration_invariant_smoothness

    def executed(duration, dt=1e-3):  # a minimum-jerk reach, sampled at 1 kHz
        t = np.arange(0.0, duration + dt / 2, dt) / duration
        q = np.outer(10 * t**3 - 15 * t**4 + 6 * t**5, [0.3, -0.5, 0.8])
        qdd = np.diff(q, 2, axis=0) / dt**2
        return float((qdd**2).sum()), duration

    fast = executed(3.0)
    slow = executed(3.6)
    assert slow[0] < 0.6 * fast[0]  # 20 % slower: (1 / 1.2)^3 = 0.58 of the raw sum
    a, b = (duration_invariant_smoothness(*x) for x in (fast, slow))
    assert abs(a - b) / a < 1e-3


def test_any_two_methods_on_the_same_environments_are_paired():
    import pandas as pd

    from analysis.table import paired

    rows = [
        {
            "task": 1,
            "method": m,
            "env": e,
            "success": True,
            "final_time": 4.0 + e + (m == "servo"),
            "sum_sq_acc": 10.0 * (e + 1),
            "sum_sq_acc_t3": 1.0,
        }
        for m in ("amex", "servo", "dmp", "dmp_ps")
        for e in range(4)
    ]
    pairs = paired(pd.DataFrame(rows))
    row = pairs[(pairs.a == "amex") & (pairs.b == "servo") & (pairs.metric == "final_time")]
    assert len(row) == 1 and row.mean_diff.iloc[0] == -1.0  # the paper's methods first
    assert len(pairs[(pairs.a == "dmp") & (pairs.b == "dmp_ps")]) == 4  # one row per metric
    assert len(pairs.groupby(["a", "b"])) == 6  # every two of the four methods


def test_an_unknown_option_is_one_line_and_exit_2(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--bogus"])
    err = capsys.readouterr().err
    assert info.value.code == 2
    assert err.startswith("make table: error: unrecognized arguments: --bogus")
    assert err.count("\n") == 1


def test_compare_sets_benchmarks_beside_the_paper_and_checks_the_claims_on_each(runs, tmp_path):
    from analysis.compare import main as compare

    assert compare([f"a={runs}", f"b={runs}", "--out", str(tmp_path)]) == 0
    md = (tmp_path / "compare.md").read_text()
    assert "| final time [s]: paper | final time [s]: a | final time [s]: b |" in md
    assert "| paper | 1.00 | 1.00 | 1.00 | 0.99 |" in md  # the paper's success by task and method
    claims = md.split("## The paper's claims on each")[1]
    assert "| claim | paper | a (as the paper computed) | a (exact) | b (as" in claims
    assert "| AMEX is smoother than DMP | holds (weakest T3: AMEX - DMP" in claims  # the paper's
    assert "| T2 dmp | " in md.split("against the paper")[1]  # every cell against the paper


def test_compare_refuses_a_bad_benchmark_argument(tmp_path, capsys):
    from analysis.compare import main as compare

    with pytest.raises(SystemExit) as info:
        compare(["nonsense", "--out", str(tmp_path)])
    assert info.value.code == 2
    assert "LABEL=DIR" in capsys.readouterr().err
    assert compare([f"x={tmp_path / 'missing'}", "--out", str(tmp_path)]) == 2
    assert not (tmp_path / "compare.md").exists()


@pytest.mark.slow
def test_a_seed_sweep_pools_into_one_benchmark_paired_on_seed_and_env(tmp_path):
    import subprocess
    import sys

    amex_run = str(Path(sys.executable).parent / "amex-run")
    sweep = tmp_path / "sweep"
    cell = ["task=1", "method=amex,dmp", "episodes=3", "max_time=2"]
    for extra in (["seed=0,1"], ["seed=2", "max_time=3"]):  # the last differs in max_time too
        proc = subprocess.run(
            [amex_run, "-m", *cell, *extra, f"hydra.sweep.dir={sweep}"],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    assert main([str(sweep), "--out", str(out)]) == 0
    index = (out / "fig5.md").read_text()
    assert "2 benchmark configurations" in index and "seeds 0, 1 pooled" in index
    pooled = next(p for p in out.glob("scene_seeds-*/fig5.md")).read_text()
    assert "| 1 | amex | 6 | 2 |" in pooled and "| 1 | dmp | 6 | 2 |" in pooled
    assert "| 1 | amex | dmp | final_time | 6 |" in pooled  # (seed, env) pairs
    assert "## Seeds: pooled, within and between" in pooled and "6 (3+3)" in pooled
    alone = [p.read_text() for p in out.glob("scene_*/fig5.md") if "seeds-" not in str(p)]
    assert len(alone) == 1 and "| 1 | amex | 3 | 1 |" in alone[0]


def test_seeds_pool_only_with_equal_code_and_configuration():
    import pandas as pd

    from analysis.pooling import _Unit

    def unit(seed, key="k", code="c"):
        return _Unit(
            pd.DataFrame(
                {
                    "seed": [seed],
                    "scene_key": [key],
                    "task": [1],
                    "variant": ["v"],
                    "code_hash": [code],
                }
            )
        )

    assert unit(0).joins(unit(1))
    assert not unit(0).joins(unit(0))  # one seed twice: another run of it, not a replicate
    assert not unit(0).joins(unit(1, key="other"))  # another configuration
    assert not unit(0).joins(unit(1, code="d"))  # other code
    assert not unit(0, code="").joins(unit(1, code=""))  # rows without a code hash
    assert not unit(0, key=None).joins(unit(1, key=None))  # no recorded configuration


def test_a_task_without_one_of_the_methods_is_tabled_not_a_traceback(runs, tmp_path):
    """A partial sweep (#23 item 14): Task 2 ran AMEX only; the table pairs what it can."""
    partial = tmp_path / "runs"
    shutil.copytree(runs, partial, ignore=shutil.ignore_patterns("task2_dmp"))
    assert main([str(partial), "--out", str(tmp_path / "out")]) == 0
    md = (tmp_path / "out" / "fig5.md").read_text()
    assert "| 2 | amex | 3 |" in md and "| 2 | dmp | 3 |" not in md
    assert "| 1 | amex | dmp | final_time" in md and "| 2 | amex | dmp |" not in md


def test_2_std_divides_by_n_minus_the_std_ddof_the_runs_recorded(runs, tmp_path):
    import numpy as np
    import pandas as pd
    import yaml

    from analysis.episodes import TableError, load_runs
    from analysis.table import aggregate

    def copy(ddof, name):
        cell = tmp_path / name
        shutil.copytree(runs / "task1_amex", cell)
        (cell / ".hydra").mkdir()
        (cell / ".hydra" / "config.yaml").write_text(yaml.safe_dump({"std_ddof": ddof}))
        return cell

    ft = load_runs(runs / "task1_amex").final_time.to_numpy()
    assert np.ptp(ft) > 0  # a spread to measure
    cells = {ddof: load_runs(copy(ddof, f"ddof{ddof}")) for ddof in (0, 1)}
    for ddof, episodes in cells.items():
        (row,) = aggregate(episodes).itertuples()
        assert row.std_ddof == ddof and row.final_time_2std == 2 * ft.std(ddof=ddof)
    with pytest.raises(TableError, match="different std_ddof"):
        aggregate(pd.concat(cells.values()))  # one cell from runs of both conventions


def test_mppi_sits_beside_cr_with_its_compute_tail_and_budget_stops(tmp_path):
    """Real CR and MPPI runs: CR, then MPPI; CPU p95, max, deadline misses and budget stops."""
    from analysis.table import TAIL_COLUMNS

    root = tmp_path / "runs"
    for name in ("mppi", "cr", "amex"):  # in no particular order
        config = RunConfig(task=1, episodes=2, max_time=3.0)
        config.method = METHODS[name].config_class()
        run(config, root / f"task1_{name}")
    assert main([str(root), "--out", str(tmp_path / "out")]) == 0
    md = (tmp_path / "out" / "fig5.md").read_text()
    rows = [line for line in md.splitlines() if line.startswith("| 1 | ")]
    assert [r.split(" | ")[1] for r in rows[:3]] == ["amex", "cr", "mppi"]
    assert all(c in md for c in TAIL_COLUMNS)
    assert "| 1 | cr | mppi | final_time |" in md  # paired on the same environments
    lines = md.splitlines()
    header = next(x for x in lines if x.startswith("| task | method | n |"))
    cells = [c.strip() for c in header.strip("|").split("|")]
    table = {}
    for row in rows[:3]:
        values = [c.strip() for c in row.strip("|").split("|")]
        table[values[1]] = dict(zip(cells, values, strict=True))
    mppi, cr = table["mppi"], table["cr"]
    assert mppi["budget stops"] != "" and cr["budget stops"] == ""
    assert float(mppi["compute CPU max [s]"]) >= float(mppi["compute CPU p95 [s]"])
