"""The kernels compiled ahead of time (amex.core.compiled): whole sources, same types, same bits.

The library is built by ``make install`` (``python -m amex.app.build_kernels``); a test that needs
it builds it first where it is missing or stale (~9 s of CPU), so an edited kernel is tested as
the library a fresh install would build.
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from amex.core import compiled
from amex.sim.metrics import TIMING_COLUMNS

PACKAGE = Path(compiled.__file__).resolve().parents[1]

#: Cells whose episodes call every exported kernel: the episode step (dynamic and kinematic, with
#: and without the collision task, ours and the authors' collision cost), AMEX's update, the
#: clearance terms of the CBF methods and RMPflow's resolve.
CELLS = (
    ("amex", 1, ()),
    ("amex", 3, ()),
    ("amex", 4, ("sim=kinematic",)),
    ("amex", 3, ("controller.collision_cost=proxy",)),
    ("dmp", 2, ()),
    ("track", 0, ()),
    ("rmpflow", 3, ()),
    ("cbf_ik", 4, ()),
    ("amex_cbf", 3, ()),
    ("dmp_avoid", 4, ()),
)

#: Run in a child (argv: a JSON list of cells): every cell's first two environments, each row
#: printed as JSON, then whether Numba was imported and each exported kernel's signatures.
CHILD = """
import importlib, json, sys
from amex.app.compose import load_config
from amex.experiment.runner import prepare, run_one
from amex.core import compiled
rows = []
for method, task, extra in json.loads(sys.argv[1]):
    config = load_config([f"method={method}", f"task={task}", "max_time=1.5", *extra])
    context = prepare(config)
    rows += [run_one(config, context, env).as_row() for env in (0, 1)]
numba = "numba" in sys.modules
signatures = {}
if numba:
    for e in compiled.EXPORTS:
        module = sys.modules.get(e.module)
        if module is not None:
            signatures[e.name] = [str(s) for s in getattr(module, e.name).signatures]
print(json.dumps({"rows": rows, "numba": numba, "signatures": signatures}, default=str))
"""


def _built() -> Path:
    """The library of today's sources, built here if missing (module notes)."""
    path = compiled.library_path()
    if not path.is_file():
        from amex.app.build_kernels import build

        build()
    return path


def _child(cells, **env: str) -> dict:
    environment = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", **env}
    done = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(cells)],
        env=environment,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])


def _amex_imports(path: Path) -> set[str]:
    """The amex modules ``path`` imports, wherever in the file (a package's own code not)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("amex.")}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("amex"):
            for a in node.names:  # a submodule by its name, else the module its names are from
                sub = f"{node.module}.{a.name}"
                found.add(sub if _file(sub) is not None else node.module)
    return found


def _file(module: str) -> Path | None:
    rel = Path(*module.split(".")[1:])
    for candidate in (PACKAGE / rel.with_suffix(".py"), PACKAGE / rel / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def test_the_fingerprint_covers_every_source_the_exported_kernels_compile():
    seen: set[Path] = set()
    todo = [_file(e.module) for e in compiled.EXPORTS]
    while todo:
        path = todo.pop()
        if path is None or path in seen:
            continue
        seen.add(path)
        todo += [_file(m) for m in _amex_imports(path)]
    needed = {str(p.relative_to(PACKAGE)) for p in seen if p.name != "__init__.py"}
    assert needed <= set(compiled.SOURCES), sorted(needed - set(compiled.SOURCES))


def test_an_edited_source_changes_the_fingerprint(tmp_path):
    for name in compiled.SOURCES:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(PACKAGE / name, tmp_path / name)
    assert compiled.digest(tmp_path) == compiled.fingerprint()
    kernel_file = tmp_path / "sim/step_kernel.py"
    kernel_file.write_text(kernel_file.read_text() + "\n# an edit\n")
    assert compiled.digest(tmp_path) != compiled.fingerprint()
    assert compiled.module_name() == f"amex_aot_{compiled.fingerprint()}"


def test_no_library_or_aot_off_hands_out_numba_dispatchers(tmp_path, monkeypatch):
    from numba.core.dispatcher import Dispatcher

    monkeypatch.setenv("AMEX_AOT_DIR", str(tmp_path))  # a directory without the library
    compiled.library.cache_clear()
    try:
        assert compiled.library() is None
        assert isinstance(compiled.kernel("amex.sim.step_kernel", "episode_step"), Dispatcher)
        monkeypatch.delenv("AMEX_AOT_DIR")
        monkeypatch.setenv("AMEX_AOT", "0")
        compiled.library.cache_clear()
        assert compiled.library() is None
        # a kernel not in the library comes from Numba whatever the switches say
        assert isinstance(compiled.kernel("amex.control.kernels", "clip_into"), Dispatcher)
    finally:
        compiled.library.cache_clear()


def test_the_library_holds_every_export_under_its_symbol():
    _built()
    compiled.library.cache_clear()
    lib = compiled.library()
    assert lib is not None
    assert lib.__name__ == compiled.module_name() and sys.modules[lib.__name__] is lib
    for e in compiled.EXPORTS:
        assert compiled.kernel(e.module, e.name) is getattr(lib, compiled.symbol(e.module, e.name))


def test_episodes_are_the_same_bits_ahead_of_time_and_without_numba():
    """The same rows with the library and with Numba's JIT, and no Numba in the library's run.

    A run that solves a plan (none cached yet) imports Numba for the optimizer; the JIT run goes
    first and leaves the plans cached for the second.

    The JIT run also records the signatures Numba compiled for each exported kernel: the
    library's wrappers convert arguments without checking their types, so every call of a run
    must have the exported types exactly (one signature each, the exported one).
    """
    _built()
    cells = [list(c) for c in CELLS]
    jit = _child(cells, AMEX_AOT="0")  # first: it solves and caches the plans (with Numba)
    ahead = _child(cells)
    assert not ahead["numba"], "a run of exported kernels imported Numba"
    assert jit["numba"]
    from amex.app.build_kernels import signature

    for e in compiled.EXPORTS:
        want = str(signature(e).args)
        assert jit["signatures"].get(e.name) == [want], (e.name, jit["signatures"].get(e.name))
    assert len(ahead["rows"]) == len(jit["rows"]) == 2 * len(CELLS)
    for a, b in zip(ahead["rows"], jit["rows"], strict=True):
        for column in a:
            if column not in TIMING_COLUMNS:
                same = a[column] == b[column] or (a[column] != a[column] and b[column] != b[column])
                assert same, (a["method"], a["task"], a["env"], column, a[column], b[column])


@pytest.mark.slow
def test_a_build_replaces_the_libraries_of_other_sources(tmp_path):
    from amex.app.build_kernels import build

    stale = tmp_path / "amex_aot_0123456789abcdef.cpython-311-x86_64-linux-gnu.so"
    stale.write_bytes(b"not a library")
    built = build(tmp_path)
    assert built.name == compiled.library_path().name and built.is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == [built.name]


def test_if_stale_builds_nothing_where_the_library_of_these_sources_is(
    tmp_path, monkeypatch, capsys
):
    from amex.app.build_kernels import main

    monkeypatch.setenv("AMEX_AOT_DIR", str(tmp_path))
    present = tmp_path / compiled.library_path().name
    present.write_bytes(b"stands in for the built library")
    assert main(["--if-stale"]) == 0
    assert present.read_bytes() == b"stands in for the built library"  # not rebuilt
    assert capsys.readouterr().out == ""
    with pytest.raises(SystemExit) as e:
        main(["--if-stale", "--fast"])
    assert e.value.code == 2
    assert "--fast" in capsys.readouterr().err
