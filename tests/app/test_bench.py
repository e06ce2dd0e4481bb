"""``make bench`` runs (its numbers are read by people, never asserted on)."""

import pytest

from amex.app.bench import main


def test_bench_times_a_method_over_task3_episodes(capsys):
    main(["--steps-only", "--methods", "track", "--episodes", "2"])
    out = capsys.readouterr().out
    assert "method track     outer step on Task 3 (2 env), median of" in out
    assert "p95" in out and "thread CPU median" in out


def test_bench_refuses_zero_episodes(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--steps-only", "--episodes", "0"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--episodes 0" in err and err.count("\n") == 1


def test_bench_times_the_replanners_on_cpu_time_per_task(capsys):
    main(["--steps-only", "--methods", "mppi", "--episodes", "1", "--tasks", "1"])
    out = capsys.readouterr().out
    assert "method mppi      outer step on Task 3 (1 env)" in out
    line = next(x for x in out.splitlines() if "Task 1 (1 env" in x)
    assert line.startswith("method mppi") and "thread CPU: median" in line and "max" in line
    assert "over 10 ms:" in line
