"""Start-up cost of ``amex-run``: the CPU a process spends besides its episodes, beside its floor.

Every SLURM array task and every joblib worker pays it, so it is measured as a whole process:
``amex-run`` with one environment of Task 0 that stops after ``STEPS`` inner steps, its user +
system CPU time read from ``getrusage(RUSAGE_CHILDREN)``. ``warm``: the Numba cache of this
install; ``cold``: an empty ``NUMBA_CACHE_DIR``, i.e. every kernel a run calls compiled again, as
on a fresh install.

Two floors, each the same interpreter with the environment ``amex-run`` sets (one BLAS thread,
no on-screen OpenGL), then exiting:

- ``floor``: importing the libraries a run calls (MuJoCo, Pinocchio, coal, Numba, SciPy's LAPACK,
  Hydra);
- ``numba_floor``: the same, and Numba's CPU target initialised, which the first call of any
  compiled function pays, cached or not (its registries of typing and lowering, and its runtime
  compiled by LLVM).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import NamedTuple

#: Inner steps of the measured episode (``max_time`` = STEPS ms): the run does its whole set-up.
STEPS = 10
#: What a run needs imported, whatever amex does (the floor).
FLOOR_IMPORTS = "numpy, mujoco, pinocchio, coal, numba, scipy.linalg.lapack, hydra, omegaconf"


#: Numba's CPU target initialised, as the first call of a compiled function does.
NUMBA_INIT = "from numba.core.registry import cpu_target; cpu_target.target_context.refresh()"
#: What ``amex-run`` sets before anything imports (amex.app.cli).
RUN_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "MUJOCO_GL": "disable",
}


class StartupTimes(NamedTuple):
    """CPU seconds (user + system) of whole processes, one per repetition."""

    warm: list[float]
    cold: list[float]
    floor: list[float]
    numba_floor: list[float]


def _child_cpu(command: list[str], env: dict[str, str], cwd: str) -> float:
    """User + system CPU [s] of one child process running ``command`` to its end."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, env=env, cwd=cwd, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _run_command(run_dir: Path) -> list[str]:
    return [
        str(Path(sys.executable).with_name("amex-run")),  # the console script users run
        "task=0",
        "method=track",
        "episodes=1",
        f"max_time={STEPS * 1e-3}",
        f"hydra.run.dir={run_dir}",
    ]


def startup_times(repeats: int = 5) -> StartupTimes:
    """Start-up CPU of ``amex-run``, warm and with a cold Numba cache, and its floor.

    The first warm run is discarded (it fills the reference plan's and Numba's caches); amex's
    bytecode is written first (:func:`amex.app.warm.warm_bytecode`, as ``make install`` does).
    """
    from amex.app.warm import warm_bytecode

    warm_bytecode()
    env = {**os.environ, **{k: os.environ.get(k, v) for k, v in RUN_ENVIRONMENT.items()}}
    times = StartupTimes([], [], [], [])
    with tempfile.TemporaryDirectory() as tmp:
        env.setdefault("AMEX_CACHE_DIR", str(Path(tmp) / "cache"))
        floor_cmd = [sys.executable, "-c", f"import gc, {FLOOR_IMPORTS}; gc.freeze()"]
        numba_cmd = [sys.executable, "-c", f"import gc, {FLOOR_IMPORTS}; {NUMBA_INIT}; gc.freeze()"]
        _child_cpu(_run_command(Path(tmp) / "run_first"), env, tmp)
        for k in range(repeats):
            times.warm.append(_child_cpu(_run_command(Path(tmp) / f"warm{k}"), env, tmp))
            fresh = dict(env, NUMBA_CACHE_DIR=str(Path(tmp) / f"numba{k}"))
            times.cold.append(_child_cpu(_run_command(Path(tmp) / f"cold{k}"), fresh, tmp))
            times.floor.append(_child_cpu(floor_cmd, env, tmp))
            times.numba_floor.append(_child_cpu(numba_cmd, env, tmp))
    return times
