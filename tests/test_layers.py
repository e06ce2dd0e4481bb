"""The layers of amex as its import graph: one direction, no cycle, no private name across modules.

Every ``import`` of the sources counts, function-local and ``TYPE_CHECKING`` ones included. A
module may import from its own package and from the packages of lower layers only; packages of
the same layer (``control`` and ``plan``) do not import each other. Only the application layer
imports Hydra or OmegaConf, and the analysis reads runs: it never starts an episode.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Layers from the ground up; a package may import only from packages of lower layers.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("amex.core",),
    ("amex.robot",),
    ("amex.control", "amex.plan"),
    ("amex.methods",),
    ("amex.sim",),
    ("amex.log",),
    ("amex.experiment",),
    ("amex.app",),
    ("hydra_plugins.amex_sweeper",),  # our sweeper, which Hydra loads: it launches app jobs
    ("analysis",),
)
HYDRA = ("hydra", "omegaconf")
#: What starts episodes: analysis reads the runs these write, it never calls them.
RUNNERS = {
    "amex.experiment.runner": {"run", "run_one", "prepare"},
    "amex.sim.episode": {"run_episode"},
}


def _sources() -> dict[str, Path]:
    modules = {}
    for base in (ROOT / "amex", ROOT / "analysis"):
        for path in base.rglob("*.py"):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts)
            if parts[:2] == ["amex", "_plugins"]:
                parts = parts[2:]  # installed as the hydra_plugins namespace
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


def imports_of(path: Path, module: str) -> list[tuple[str, list[str], int]]:
    """``(imported module, names, line)`` of every import in ``path``, relative ones resolved."""
    tree = ast.parse(path.read_text())
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(a.name, [], node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = node.module or ""
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join([*base, target] if target else base)
            found.append((target, [a.name for a in node.names], node.lineno))
    return found


def layer_of(module: str) -> tuple[int, str] | None:
    """``(rank, package)`` of a module of ours, None for third-party modules and ``amex`` itself."""
    for rank, packages in enumerate(LAYERS):
        for package in packages:
            if module == package or module.startswith(package + "."):
                return rank, package
    return None


def violations(sources: dict[str, Path]) -> list[str]:
    """Every import against the layer order, the Hydra rule, privacy or the analysis rule."""
    found = []
    for module, path in sorted(sources.items()):
        here = layer_of(module)
        for target, names, line in imports_of(path, module):
            where = f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{line}"
            hydra_ok = here is not None and here[1] in ("amex.app", "hydra_plugins.amex_sweeper")
            if target.split(".")[0] in HYDRA and not hydra_ok:
                found.append(f"{where}: {module} imports {target} (only amex.app imports Hydra)")
            there = layer_of(target)
            if here is None or there is None:
                continue
            if there[1] != here[1] and there[0] >= here[0]:
                found.append(f"{where}: {module} ({here[1]}) imports {target} ({there[1]})")
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private and target != module:
                found.append(f"{where}: {module} imports private {', '.join(private)} of {target}")
            if here[1] == "analysis" and set(names) & RUNNERS.get(target, set()):
                found.append(f"{where}: analysis calls {target}: it reads runs, never starts one")
    return found


def cycles(sources: dict[str, Path]) -> list[list[str]]:
    """Import cycles between our modules (a package counts as its ``__init__``)."""
    graph: dict[str, set[str]] = {m: set() for m in sources}
    for module, path in sources.items():
        for target, names, _ in imports_of(path, module):
            for candidate in [f"{target}.{n}" for n in names] + [target]:
                if candidate in sources and candidate != module:
                    graph[module].add(candidate)
                    break
    found, state = [], dict.fromkeys(graph, 0)
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state[nxt] == 1:
                found.append(stack[stack.index(nxt) :] + [nxt])
            elif state[nxt] == 0:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if state[node] == 0:
            visit(node)
    return found


def test_every_import_follows_the_layers():
    assert violations(_sources()) == []


def test_no_module_imports_itself_back_through_a_cycle():
    assert cycles(_sources()) == []


def test_every_package_of_ours_has_a_layer():
    packages = {m.split(".")[0] + "." + m.split(".")[1] for m in _sources() if m.count(".") >= 1}
    packages = {p for p in packages if p.startswith("amex.")}
    assert sorted(p for p in packages if layer_of(p) is None) == []


@pytest.mark.parametrize(
    ("module", "code", "broken"),
    [
        ("amex.core.fake", "from amex.robot import load_robot\n", "imports amex.robot"),
        ("amex.control.fake", "from amex.plan.spline import QuadraticBSpline\n", "amex.plan"),
        ("amex.sim.fake", "from hydra import compose\n", "only amex.app imports Hydra"),
        ("amex.sim.fake", "from amex.experiment.config import _private\n", "private _private"),
        ("analysis.fake", "from amex.experiment.runner import run_one\n", "never starts one"),
    ],
)
def test_an_injected_upward_import_is_found(tmp_path, module, code, broken):
    path = tmp_path / "fake.py"
    path.write_text(code)
    assert any(broken in v for v in violations({**_sources(), module: path}))


def test_an_injected_cycle_is_found(tmp_path):
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("from amex.core import b\n")
    b.write_text("import amex.core.a\n")
    found = cycles({**_sources(), "amex.core.a": a, "amex.core.b": b})
    assert ["amex.core.a", "amex.core.b", "amex.core.a"] in found
