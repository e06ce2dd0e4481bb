"""The garbage collector of an ``amex-run`` process: what set-up built is not traversed again.

A run's process holds a large heap of long-lived objects (the modules of MuJoCo, Pinocchio, Numba
and Hydra, the composed configurations, the compiled kernels' dispatchers). Python's cyclic
collector walks all of them in every full collection, and once more at exit, where that walk
alone measured ~0.3-0.4 s of CPU per process (``make bench``, start-up), paid by every run, every
sweep worker and every SLURM array task. :func:`settle` moves what exists once a job is set up into
the collector's permanent generation (``gc.freeze``), and again at exit, so neither the episodes'
collections nor the interpreter's last one walk it again. Objects are still freed by reference
counting; only cycles created before the freeze stay allocated. Nothing a run computes depends on
it.

``amex-run`` also starts without the cyclic collector (:func:`hold`) until :func:`settle`: the
imports and the composition allocate ~120,000 long-lived objects, and the collections they
trigger walked them ~390 times (measured 0.12-0.16 s of CPU per process, ``gc.callbacks``).
Without them, the cycles left at the freeze are ~13,500 objects, ~1.7 MB (with the collector on
during start-up: ~4,700 objects, 0.5 MB), allocated once per process.
"""

from __future__ import annotations

import atexit
import gc

_AT_EXIT: list[bool] = []


def hold() -> None:
    """Start-up without the cyclic collector, until :func:`settle` (module notes)."""
    gc.disable()


def settle() -> None:
    """Freeze the heap built so far and collect cycles again from here on (module notes).

    At exit, whatever is left is frozen too.
    """
    gc.freeze()
    gc.enable()
    if not _AT_EXIT:
        atexit.register(gc.freeze)
        _AT_EXIT.append(True)
