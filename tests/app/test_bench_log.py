"""The log-cost benchmark (:mod:`amex.app.bench_log`): what it measures (no time asserted)."""

import numpy as np
import pytest

from amex.app.bench_log import log_overhead, main


def test_log_overhead_times_each_environment_plain_and_logged():
    result = log_overhead(3, "amex", range(2), ["max_time=0.2"], verbose=False)
    assert all(len(part) == 2 for part in result)
    assert np.all(result.plain_cpu > 0) and np.all(result.logged_cpu > 0)
    assert np.all(result.plain_wall > 0) and np.all(result.logged_wall > 0)
    np.testing.assert_allclose(result.overhead("wall"), result.logged_wall / result.plain_wall - 1)
    with pytest.raises(ValueError, match="valid: thread, wall"):
        result.overhead("process")


def test_main_prints_one_summary_line_per_task_and_method(capsys):
    main(["max_time=0.1", "--tasks", "1", "--methods", "dmp", "--episodes", "1", "--quiet"])
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith("Task 1, dmp (1 env): log=full overhead")
