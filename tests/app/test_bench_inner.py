"""The inner-step benchmark (:mod:`amex.app.bench_inner`): what it measures (no time asserted)."""

import numpy as np

from amex.app.bench_inner import inner_step, main, measure


def test_measure_times_every_step_and_marks_the_margin_and_the_outer_steps():
    steps = measure(3, "amex", range(1), ["max_time=0.3"])
    n = len(steps.step_cpu)
    assert n == 300  # 0.3 s at 1 kHz: every step that ran to its end
    assert all(len(part) == n for part in steps)
    assert np.all(steps.step_cpu > 0) and np.all(steps.floor_cpu > 0)
    assert np.all(steps.step_wall > 0) and np.all(steps.floor_wall > 0)
    np.testing.assert_array_equal(steps.outer, np.arange(n) % 10 == 0)
    assert np.all(steps.method_cpu[steps.outer] > 0) and np.all(steps.method_cpu[~steps.outer] == 0)
    assert steps.in_margin.dtype == bool


def test_inner_step_leaves_the_outer_steps_out():
    times = inner_step(0, "amex", range(1), "wall", ["max_time=0.1"])
    assert len(times.step_times) == len(times.floor_times) == len(times.in_margin_mask) == 90
    assert not times.in_margin_mask.any()  # Task 0 has no obstacle


def test_main_prints_the_table(capsys):
    main(["max_time=0.1", "--tasks", "0", "--methods", "amex"])
    out = capsys.readouterr().out
    assert "Task 0, amex (1 env, 100 steps)" in out
    assert "inner out of margin" in out and "ratio" in out and "outer steps" in out
