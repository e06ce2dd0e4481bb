"""Compile every Numba kernel of amex into Numba's cache once, so that runs start warm.

The compiled kernels (the OSC, the collision tasks, AMEX's update, the planner's batched
kinematics, the reactive methods', MPPI's rollouts) are cached by Numba (``cache=True``): in the
package's ``__pycache__`` or under ``NUMBA_CACHE_DIR``, one entry per kernel signature and CPU
model. A process that finds no entry compiles the kernels it calls (~4-5 s of CPU for a run of
AMEX on Task 3 with the ahead-of-time library off, ``make bench``, start-up; with it, only the
kernels outside it: CR's, MPPI's, the planner's, the observer's, the log's).
``python -m amex.app.warm`` (run by ``make install``) fills the cache by running a few steps of
every registered method on an obstacle task, with our collision cost and the authors', dynamic
and kinematic, and the disturbance observer, and once with an MCAP log (the log's encoders are
compiled too: ~7 s of CPU at the first ``log=full`` run otherwise), so that the first run of
every method is already warm. On a cluster, run it once per CPU model with ``NUMBA_CACHE_DIR``
on the shared file system (docs/clusters.md).

It also writes the bytecode of amex's modules (:func:`warm_bytecode`), as ``pip`` does for a
wheel but not for an editable install: without it, a process started with
``PYTHONDONTWRITEBYTECODE=1`` (or from a read-only checkout) compiles every amex module again,
~0.1-0.2 s of CPU at each start.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

#: The variants whose kernels differ besides the method (Hydra overrides), each run briefly.
VARIANTS: tuple[tuple[str, ...], ...] = (
    ("task=3",),
    ("task=3", "controller.collision_cost=proxy"),
    ("task=4", "sim=kinematic"),
    ("task=3", "controller.disturbance=observer"),
    ("task=3", "controller.disturbance=integral"),
)
#: Simulated seconds of each warm-up episode: a few outer steps, the collision task reached.
WARM_TIME = 0.05


def warm(methods: list[str] | None = None, quiet: bool = False) -> float:
    """Run a short episode of each method in each variant; return the CPU seconds it took."""
    from amex.app.compose import load_config
    from amex.core.errors import AmexError
    from amex.experiment.runner import prepare, run_one
    from amex.methods import METHODS

    start = time.process_time()
    with tempfile.TemporaryDirectory(prefix="amex-warm-") as tmp:
        for name in methods or sorted(METHODS):
            for k, variant in enumerate(VARIANTS):
                overrides = [f"method={name}", *variant, f"max_time={WARM_TIME}"]
                log = Path(tmp) / f"{name}.mcap" if k == 0 else None  # the log's kernels, once
                try:
                    config = load_config(overrides)
                    run_one(config, prepare(config), 0, log)
                except AmexError as e:  # a variant a method does not take: skip it
                    if not quiet:
                        sys.stderr.write(f"warm: {' '.join(overrides)} skipped: {e}\n")
    return time.process_time() - start


def warm_bytecode() -> bool:
    """Write the bytecode (``__pycache__/*.pyc``) of every module of amex; True if all compiled."""
    import compileall

    package = Path(__file__).resolve().parents[1]
    return bool(compileall.compile_dir(str(package), quiet=1))


def main() -> None:
    """``python -m amex.app.warm [METHOD ...]``: fill Numba's cache (module notes)."""
    # the exported kernels too, as Numba compiles them (AMEX_AOT=0 runs, and the library's build)
    os.environ["AMEX_AOT"] = "0"
    warm_bytecode()
    cpu = warm(sys.argv[1:] or None)
    sys.stdout.write(f"Numba cache warm ({cpu:.1f} s of CPU)\n")


if __name__ == "__main__":
    main()
