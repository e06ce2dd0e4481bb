"""``make bench`` runs (its numbers are read by people, never asserted on)."""

import numpy as np
import pytest

from amex.app.bench import main


def test_bench_times_a_method_over_task3_episodes(capsys):
    main(["--steps-only", "--methods", "track", "--episodes", "2", "--tasks", "3"])
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.strip().startswith("track"))
    assert "Task 3 (2 env," in line and "median" in line and "p95" in line and "wall median" in line


def test_bench_refuses_zero_episodes(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--steps-only", "--episodes", "0"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--episodes 0" in err and err.count("\n") == 1


def test_bench_times_the_replanners_on_cpu_time_per_task(capsys):
    main(["--steps-only", "--methods", "mppi", "--episodes", "1", "--tasks", "1"])
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.strip().startswith("mppi"))
    assert "Task 1 (1 env" in line and "median" in line and "max" in line
    assert "over 10 ms" in line


def test_bench_puts_amex_beside_its_target(capsys):
    main(["--steps-only", "--methods", "amex", "--episodes", "1", "--tasks", "2"])
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.strip().startswith("amex"))
    assert "target" in line and "5.0 us" in line


@pytest.mark.slow
def test_startup_is_timed_warm_cold_and_beside_both_floors():
    from amex.app.bench_startup import startup_times

    times = startup_times(repeats=1)
    assert all(len(v) == 1 and v[0] > 0 for v in times)


def test_startup_phases_add_up_to_the_whole_process():
    """Every phase is timed around what amex-run really calls: a renamed function, a phase never
    reached or a phase counted twice breaks the sum or a bound."""
    from amex.app.bench_startup import PHASES, startup_phases

    phases = startup_phases(repeats=1)
    assert set(phases) == {key for key, _ in PHASES} | {"total"}
    spent = {key: values[0] for key, values in phases.items()}
    total = spent.pop("total")
    assert sum(spent.values()) == pytest.approx(total, abs=1e-9)
    for key in ("libraries", "numba", "amex_imports", "schemas", "composition", "episode"):
        assert spent[key] > 0.0, key
    # the libraries are the largest part of a warm start-up; no phase is negative beyond the
    # resolution of the two clocks compared (getrusage's total, process_time's phases)
    assert spent["libraries"] == max(spent.values())
    assert min(spent.values()) > -0.01


def test_cr_floor_replays_the_compiled_loops_own_calls(monkeypatch):
    """The floor of a step on the compiled loop: its kinematics kernel in place of Pinocchio's
    three calls, LAPACK's dpbsv, and nothing of the step's Python."""
    import pinocchio as pin
    import scipy.linalg.lapack as lapack

    from amex.app import bench_cr
    from amex.plan.optimizer.compiled_loop import tcp_kinematics

    replayed = []
    replay = bench_cr._replay
    monkeypatch.setattr(bench_cr, "_replay", lambda calls: replayed.append(calls) or replay(calls))
    result = bench_cr.cr_floor(1, range(1), ("max_time=0.3",))
    solving = [i for i, n in enumerate(result.iterations) if n > 0]
    assert solving and all(result.floor_cpu[i] > 0.0 for i in solving)  # (no time compared)
    functions = {fn for calls in replayed for fn, _, _ in calls}
    assert tcp_kinematics in functions and lapack.dpbsv in functions
    assert not functions & {pin.computeJointJacobians, pin.getFrameJacobian}
    # the step is timed in its own run, the floor in a second run of the same steps
    assert len(result.step_cpu) == len(result.recorded_cpu) == len(result.floor_cpu) == 30


def test_cr_floor_refuses_two_runs_that_took_different_steps(monkeypatch):
    from amex.app import bench_cr

    recorded = bench_cr._recorded_episode
    monkeypatch.setattr(bench_cr, "_recorded_episode", lambda *a: recorded(*a)[:-1])
    with pytest.raises(RuntimeError, match="differ"):
        bench_cr.cr_floor(1, range(1), ("max_time=0.1",))


def test_a_bench_episode_raises_the_error_its_step_raised(monkeypatch):
    """An episode records a method's error and ends; a bench must not time the shorter run."""
    from amex.app import bench_cr
    from amex.methods.cr import CR

    def broken(self):
        raise AttributeError("no such thing")

    monkeypatch.setattr(CR, "target", broken)
    with pytest.raises(RuntimeError, match="AttributeError: no such thing"):
        bench_cr.path_times(1, range(1), ("max_time=0.1",))


def test_cr_paths_are_timed_step_by_step_on_the_same_observations():
    """``bench_cr --paths``: CR's one-call step and solve_trajectory's, step for step."""
    from amex.app import bench_cr

    one_call, solver = bench_cr.path_times(1, range(1), ("max_time=0.3",))
    assert len(one_call) == len(solver) == 30  # the same steps (no time compared)
    assert np.all(one_call > 0) and np.all(solver > 0)
