"""Build the ahead-of-time library of the episode loop's kernels (:mod:`amex.core.compiled`).

``python -m amex.app.build_kernels`` (run by ``make install``, after Numba's cache is warm)
compiles every kernel of :data:`amex.core.compiled.EXPORTS` with Numba's ahead-of-time compiler
(``numba.pycc``) into one C extension, named after the sources' fingerprint, in
:func:`amex.core.compiled.library_dir`, and removes the libraries of other sources there. Each
kernel's return type is the one Numba's JIT infers for the same arguments, so the two are the
same compilation of the same source. It needs a C compiler (``cc``); where it fails, runs go on
with Numba's JIT (a warning, exit 1), as they do where the library was never built.

The library is built for the generic x86-64 CPU, so one build serves every machine of a cluster
that shares the install (docs/clusters.md); it loads only into the Python and Numba it was built
with (the fingerprint names both).
"""

from __future__ import annotations

import importlib
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from amex.core import compiled

__all__ = ["build", "main", "signature"]


def _type(token: str) -> Any:
    """The Numba type one word of :attr:`~amex.core.compiled.Export.args` spells."""
    from numba import types

    scalars = {"f": types.float64, "i": types.int64, "b": types.boolean}
    kind, ndim = token[0], token[1:]
    if kind not in scalars or (ndim and not ndim.isdigit()):
        raise ValueError(f"argument type {token!r}: expected f, i, b, fN or iN")
    if not ndim:
        return scalars[kind]
    return types.Array(scalars[kind], int(ndim), "C")


def signature(export: compiled.Export) -> Any:
    """The full signature of ``export``: its argument types, and the JIT's return type for them."""
    args = tuple(_type(token) for token in export.args.split())
    dispatcher = getattr(importlib.import_module(export.module), export.name)
    dispatcher.compile(args)  # from Numba's cache where warm
    return dispatcher.overloads[args].signature


def build(output_dir: Path | None = None) -> Path:
    """Compile :data:`~amex.core.compiled.EXPORTS` into the library; return its path."""
    import warnings

    from numba.core.errors import NumbaPendingDeprecationWarning

    with warnings.catch_warnings():  # pycc's deprecation notice: it is what numba ships today
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        from numba.pycc import CC

    target = output_dir or compiled.library_dir()
    target.mkdir(parents=True, exist_ok=True)
    cc = CC(compiled.module_name(), source_module=compiled)
    cc.target_cpu = "x86-64"  # generic: one build for every machine (module notes)
    for export in compiled.EXPORTS:
        dispatcher = getattr(importlib.import_module(export.module), export.name)
        cc.export(compiled.symbol(export.module, export.name), signature(export))(
            dispatcher.py_func
        )
    built = target / compiled.library_path().name
    with tempfile.TemporaryDirectory(prefix="amex-aot-", dir=target) as tmp:
        cc.output_dir, cc.output_file = tmp, built.name
        cc.compile()
        os.replace(Path(tmp) / built.name, built)  # whole or not at all, for a run loading it
    for stale in target.glob("amex_aot_*"):
        if stale != built:
            stale.unlink(missing_ok=True)
    return built


def main(argv: list[str] | None = None) -> int:
    """``python -m amex.app.build_kernels``: build the library (module notes); 1 if it failed.

    ``--if-stale``: only where the library of today's sources is missing (what ``make run``,
    ``make test``, ``make paper`` and ``make bench`` do first, so an edited kernel is built).
    """
    from amex.app.argparsing import OneLineParser

    parser = OneLineParser(prog="build_kernels", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--if-stale", action="store_true", help="build only if today's library is missing"
    )
    args = parser.parse_args(argv)
    if args.if_stale and compiled.library_path().is_file():
        return 0
    start = time.process_time()
    try:
        path = build()
    except Exception as e:  # no compiler, or pycc failed: runs use Numba's JIT
        sys.stderr.write(
            f"build_kernels: not built ({type(e).__name__}: {e}); runs use Numba's JIT\n"
        )
        return 1
    sys.stdout.write(
        f"kernels built ahead of time: {path.name} ({time.process_time() - start:.1f} s of CPU)\n"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
