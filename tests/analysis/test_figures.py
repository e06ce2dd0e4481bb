"""Fig. 4 and Fig. 6 drawn from the logs of their configured runs (conf/experiment/fig*.yaml)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

from analysis import figures  # noqa: E402
from analysis.fig4 import logs_of  # noqa: E402
from analysis.fig6 import farthest_goal, trace_of  # noqa: E402


def _amex_run(args, cwd):
    env = {k: v for k, v in os.environ.items() if k != "AMEX_DEBUG"}
    command = [str(Path(sys.executable).parent / "amex-run"), *args]
    proc = subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]


@pytest.mark.slow
def test_make_figures_draws_fig4_and_fig6_from_the_logged_runs(tmp_path):
    fig4, fig6 = tmp_path / "fig4", tmp_path / "fig6"
    _amex_run(["-m", "experiment=fig4", "max_time=0.4", f"hydra.sweep.dir={fig4}"], tmp_path)
    _amex_run(["experiment=fig6", "episodes=3", "max_time=0.4", f"hydra.run.dir={fig6}"], tmp_path)
    logs, shared = logs_of(fig4)
    assert list(logs) == ["amex", "dmp", "cr"] and shared == ("max_time=0.4",)
    trace = trace_of(farthest_goal(fig6), "AMEX")
    assert trace.tcp.shape == trace.goal.shape == (len(trace.t), 3)
    assert len(trace.s) == len(trace.speed) == len(trace.t) and trace.t[-1] <= 0.4 + 1e-9
    out = tmp_path / "out"
    args = ["--runs", str(fig6), "--fig4", str(fig4), "--fig6", str(fig6), "--out", str(out)]
    assert figures.main(args) == 0
    for name in ("fig4_task3_0.4.png", "fig6_task2.png", "fig2_amex.png", "fig5.png"):
        assert (out / name).stat().st_size > 10_000


def test_a_figure_without_its_runs_is_one_line_and_exit_2(tmp_path, capsys):
    args = ["--runs", str(tmp_path), "--fig4", str(tmp_path / "none"), "--out", str(tmp_path)]
    assert figures.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("make figures: error: ") and "experiment=fig4" in err[-1]
