"""Start-up cost of ``amex-run``: the CPU a process spends besides its episodes, beside its floor.

Every SLURM array task and every joblib worker pays it, so it is measured as a whole process:
``amex-run`` with one environment of Task 0 that stops after ``STEPS`` inner steps, its user +
system CPU time read from ``getrusage(RUSAGE_CHILDREN)``. ``warm``: the caches of this install
(the kernels built ahead of time, :mod:`amex.core.compiled`, and Numba's cache); ``cold``: an empty
``NUMBA_CACHE_DIR`` as on a machine of a cluster that shares the install but not its Numba cache
(every kernel outside the ahead-of-time library compiled again); ``jit``: warm, with the library
off (``AMEX_AOT=0``), the run's kernels from Numba's cache, as before it existed.

Two floors, each the same interpreter with the environment ``amex-run`` sets (one BLAS thread,
no on-screen OpenGL), then exiting:

- ``floor``: importing the libraries a run calls (MuJoCo, Pinocchio, coal, SciPy's LAPACK,
  Hydra);
- ``numba_floor``: the same, Numba imported and its CPU target initialised, which the first call
  of any Numba-compiled function pays, cached or not (its registries of typing and lowering, and
  its runtime compiled by LLVM): the floor of a run whose kernels are not all ahead of time (CR,
  MPPI, ``log=full``).

:func:`startup_phases` splits a warm start-up into its phases (:data:`PHASES`), each timed in
the process itself (``time.process_time``) around the functions ``amex-run`` calls: the
libraries and the kernels (loaded, or Numba's target) first, then amex's imports, Hydra's
ConfigStore, Hydra's composition, amex's checks of it, Hydra's job around amex's, and the
episode. What the process spends before its first line and after its last (the interpreter's
start and exit) is the whole process's CPU minus their sum.
"""

from __future__ import annotations

import contextlib
import os
import resource
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

#: Inner steps of the measured episode (``max_time`` = STEPS ms): the run does its whole set-up.
STEPS = 10
#: What a run needs imported, whatever amex does (the floor); Numba only where its kernels are
#: not built ahead of time (:mod:`amex.core.compiled`).
FLOOR_IMPORTS = "numpy, mujoco, pinocchio, coal, scipy.linalg.lapack, hydra, omegaconf"


#: Numba's CPU target initialised, as the first call of a compiled function does.
NUMBA_INIT = "from numba.core.registry import cpu_target; cpu_target.target_context.refresh()"
#: What ``amex-run`` sets before anything imports (amex.app.cli).
RUN_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "MUJOCO_GL": "disable",
}


#: The phases of a warm start-up (:func:`startup_phases`), in the order they happen.
PHASES = (
    ("libraries", "importing the libraries (the floor)"),
    ("numba", "the kernels: ahead of time loaded, or Numba imported and its target"),
    ("amex_imports", "amex's modules"),
    ("schemas", "the schemas stored in Hydra's ConfigStore"),
    ("composition", "Hydra composing the command line's config"),
    ("checks", "amex checking the config and the run directory"),
    ("hydra_job", "Hydra's job around amex's (run directory, logging, .hydra files)"),
    ("job", "amex's job besides its episode (results written)"),
    ("episode", f"the episode's set-up and its {STEPS} steps"),
    ("other", "amex-run's own rest (arguments, launch lock, Hydra's search path)"),
    ("interpreter", "the interpreter's start and exit"),
)

#: Run in a child (argv: the output file, then amex-run's arguments): amex-run's warm start-up
#: with each phase's process CPU time recorded around the functions that make it.
_PHASES_SCRIPT = f"""
import atexit, json, sys, time
out, sys.argv = sys.argv[1], ["amex-run", *sys.argv[2:]]
cpu = time.process_time
start = cpu()
spent = {{"boot": start}}
import {FLOOR_IMPORTS}
spent["libraries"] = cpu() - start
start = cpu()
from amex.core import compiled
if compiled.library() is None:  # Numba's JIT: imported and its target initialised
    import numba
    {NUMBA_INIT}
spent["numba"] = cpu() - start
start = cpu()
import amex.app.cli, amex.app.checks, amex.app.compose, amex.app.job, amex.app.launch
import amex.experiment.runner
spent["amex_imports"] = cpu() - start

def timed(module, name, key):
    inner = getattr(module, name)
    def call(*args, **kwargs):
        begin = cpu()
        try:
            return inner(*args, **kwargs)
        finally:
            spent[key] = spent.get(key, 0.0) + cpu() - begin
    setattr(module, name, call)

timed(amex.app.compose, "register_schemas", "schemas")
timed(amex.app.launch, "compose_run", "composition")
timed(amex.app.checks, "validate_command_line", "validation")
timed(amex.app.launch, "run_composed", "run_composed")
timed(amex.app.job, "task", "task")
timed(amex.experiment.runner, "run_setup", "episode")
def report():  # an exit handler: amex-run's quick exit runs it (amex.app.cli.exit_quickly)
    spent["in_process"] = cpu()
    with open(out, "w") as f:
        json.dump(spent, f)

atexit.register(report)
amex.app.cli.main()
"""


class StartupTimes(NamedTuple):
    """CPU seconds (user + system) of whole processes, one per repetition."""

    warm: list[float]
    cold: list[float]
    jit: list[float]
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


@contextlib.contextmanager
def _warmed() -> Iterator[tuple[dict[str, str], str]]:
    """The environment of the measured runs and their directory, after a first, uncounted run.

    amex's bytecode is written first (:func:`amex.app.warm.warm_bytecode`, as ``make install``
    does); the first run fills the reference plan's and Numba's caches.
    """
    from amex.app.warm import warm_bytecode

    warm_bytecode()
    env = {**os.environ, **{k: os.environ.get(k, v) for k, v in RUN_ENVIRONMENT.items()}}
    with tempfile.TemporaryDirectory() as tmp:
        env.setdefault("AMEX_CACHE_DIR", str(Path(tmp) / "cache"))
        _child_cpu(_run_command(Path(tmp) / "run_first"), env, tmp)
        yield env, tmp


def startup_times(repeats: int = 5) -> StartupTimes:
    """Start-up CPU of ``amex-run``, warm and with a cold Numba cache, and its floor.

    The first warm run is discarded (it fills the reference plan's and Numba's caches); amex's
    bytecode is written first (:func:`amex.app.warm.warm_bytecode`, as ``make install`` does).
    """
    times = StartupTimes([], [], [], [], [])
    with _warmed() as (env, tmp):
        floor_cmd = [sys.executable, "-c", f"import gc, {FLOOR_IMPORTS}; gc.freeze()"]
        with_numba = f"import gc, numba, {FLOOR_IMPORTS}; {NUMBA_INIT}; gc.freeze()"
        numba_cmd = [sys.executable, "-c", with_numba]
        jit = dict(env, AMEX_AOT="0")
        for k in range(repeats):
            times.warm.append(_child_cpu(_run_command(Path(tmp) / f"warm{k}"), env, tmp))
            fresh = dict(env, NUMBA_CACHE_DIR=str(Path(tmp) / f"numba{k}"))
            times.cold.append(_child_cpu(_run_command(Path(tmp) / f"cold{k}"), fresh, tmp))
            times.jit.append(_child_cpu(_run_command(Path(tmp) / f"jit{k}"), jit, tmp))
            times.floor.append(_child_cpu(floor_cmd, env, tmp))
            times.numba_floor.append(_child_cpu(numba_cmd, env, tmp))
    return times


def startup_phases(repeats: int = 3) -> dict[str, list[float]]:
    """CPU seconds of each phase of a warm start-up (:data:`PHASES`), one entry per repetition.

    Each repetition is one child process running ``amex-run``'s warm start-up with its phases
    timed (module notes); a first, untimed run fills the caches. ``total`` is the whole
    process's user + system CPU, as :func:`startup_times` measures it.
    """
    import json

    phases: dict[str, list[float]] = {key: [] for key, _ in PHASES}
    phases["total"] = []
    with _warmed() as (env, tmp):
        for k in range(repeats):
            out = Path(tmp) / f"phases{k}.json"
            command = [sys.executable, "-c", _PHASES_SCRIPT, str(out)]
            command += _run_command(Path(tmp) / f"phases{k}")[1:]
            total = _child_cpu(command, env, tmp)
            spent = json.loads(out.read_text())
            spent["checks"] = spent.pop("validation") - spent["composition"]
            spent["hydra_job"] = spent.pop("run_composed") - spent["task"]
            spent["job"] = spent.pop("task") - spent["episode"]
            boot, in_process = spent.pop("boot"), spent.pop("in_process")
            # the interpreter's part: before the script's first line and after its exit handler
            spent["interpreter"] = boot + total - in_process
            timed = sum(spent[key] for key, _ in PHASES if key not in ("other", "interpreter"))
            spent["other"] = in_process - boot - timed
            for key in phases:
                phases[key].append(total if key == "total" else spent[key])
    return phases
