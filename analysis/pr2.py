"""``python -m analysis.pr2``: the pr2_like study's report from its sweep's runs.

The paper's PR2 experiment (Section IV-B) in simulation (``experiment=pr2_like``): every method
on Tasks 1-4 under a 20 Hz adaptation loop, a camera-tracked goal and an arm heavier than its
model, with each disturbance compensation of the inner controller, an AMEX variant, why AMEX
stalls, and the Fig. 6 episodes. Reads the runs of ``amex-run -m study=pr2_like``
(``conf/study/pr2_like.yaml``, in ``runs/pr2_like/``; :mod:`analysis.pr2_study`) and runs no
episode. Writes ``analysis/out/pr2_like.md`` (:mod:`analysis.pr2_report`) and
``fig6_pr2_like.png`` (:mod:`analysis.fig6`). The findings: ``docs/studies.md``.

Usage: ``python -m analysis.pr2 [RUNS] [--out DIR]`` (RUNS: runs/pr2_like).
"""

from __future__ import annotations

import os
from pathlib import Path

from amex.app.argparsing import OneLineParser

from . import default_out
from .fig6 import plot_fig6, trace_of
from .pr2_report import render
from .pr2_study import PR2Study, read_study
from .sweep import StudyError


def fig6_title(study: PR2Study) -> str:
    """Fig. 6's title: the conditions of the logged episodes."""
    cell = study.fig6[0][1]
    return (
        f"Fig. 6 analogue: pr2_like ({cell.get('outer_hz'):g} Hz, camera "
        f"{1e3 * cell.get('perception.noise_std'):g} mm / "
        f"{1e3 * cell.get('perception.latency'):g} ms, mass x {cell.get('mismatch.mass_scale'):g}"
        f", friction, damping), Task {cell.get('task')}, environment 0, AMEX"
    )


def write_fig6(study: PR2Study, path: Path) -> Path:
    """Fig. 6 from the first episode of each logged cell (:mod:`analysis.fig6`)."""
    traces = []
    for label, cell in study.fig6:
        logs = sorted(log for d in cell.dirs for log in (d / "logs").glob("episode_000.mcap"))
        if not logs:
            raise StudyError(
                f"{study.sweep.runs}: no log of Fig. 6's episode ({label}); run the study's "
                "sweep (the same command resumes)"
            )
        traces.append(trace_of(logs[0], label))
    if not traces:
        raise StudyError(f"{study.sweep.runs}: no logged cells for Fig. 6 in the sweep")
    return plot_fig6(traces, path, fig6_title(study))


def write_outputs(runs: Path, out_dir: Path) -> list[Path]:
    """Read the study's runs and write ``pr2_like.md`` and ``fig6_pr2_like.png``."""
    study = read_study(runs)
    out_dir.mkdir(parents=True, exist_ok=True)
    md = out_dir / "pr2_like.md"
    tmp = md.with_suffix(".md.tmp")
    tmp.write_text(render(study))
    fig = write_fig6(study, out_dir / "fig6_pr2_like.png")
    os.replace(tmp, md)
    return [md, fig]


def main(argv: list[str] | None = None) -> int:
    """Command line (see the module docstring)."""
    from amex.core.errors import AmexError

    from . import print_written

    parser = OneLineParser(prog="python -m analysis.pr2", description=__doc__)
    parser.add_argument("runs", nargs="?", type=Path, default=Path("runs/pr2_like"))
    parser.add_argument("--out", type=Path, default=default_out())
    args = parser.parse_args(argv)
    return print_written(
        "python -m analysis.pr2", lambda: write_outputs(args.runs, args.out), (AmexError,)
    )


if __name__ == "__main__":
    raise SystemExit(main())
