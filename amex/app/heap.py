"""The garbage collector of an ``amex-run`` process: what set-up built is not traversed again.

A run's process holds a large heap of long-lived objects (the modules of MuJoCo, Pinocchio, Numba
and Hydra, the composed configurations, the compiled kernels' dispatchers). Python's cyclic
collector walks all of them in every full collection, and once more at exit, where that walk
alone measured ~0.3-0.4 s of CPU per process (``make bench``, start-up), paid by every run, every
sweep worker and every SLURM array task. :func:`settle` moves what exists once a job is set up into
the collector's permanent generation (``gc.freeze``), and again at exit, so neither the episodes'
collections nor the interpreter's last one walk it again. Objects are still freed by reference
counting; only cycles created before the freeze stay allocated (the set-up's few, measured below
1 MB). Nothing a run computes depends on it.
"""

from __future__ import annotations

import atexit
import gc

_AT_EXIT: list[bool] = []


def settle() -> None:
    """Freeze the heap built so far (module notes); at exit, freeze whatever is left too."""
    gc.freeze()
    if not _AT_EXIT:
        atexit.register(gc.freeze)
        _AT_EXIT.append(True)
