"""MkDocs hooks of the amex documentation site, and the generators behind its generated pages.

* The configuration reference (``reference/configuration.md``) is written at build time from the
  config dataclasses: :class:`amex.experiment.config.RunConfig` with every nested node, and the
  config class of every built-in method (``amex.methods.METHODS[name].config_class``). One table
  per node: key, type, default, unit and meaning. The meaning is the field's entry in the
  docstring's ``Attributes:`` section (the class or a base class); the unit is the ``# [unit]``
  comment on the field's declaration, else the first ``[...]`` in that entry; a field marked
  ``scaled(p)`` (:mod:`amex.core.scaling`) is stated in the original scene's units and carries
  ``scenario.scale ** p``. It is never committed, so it cannot drift from the code.
* The results tables the pages include (``docs/generated/``) are what the analysis commands in
  :data:`TABLES` write for the runs committed under ``docs/data/``; ``make docs-tables`` (this
  file run as a script) writes them again, and ``tests/docs/`` fails when they differ.

Only :func:`on_files` needs MkDocs; everything else imports without it (the tests use it).
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import io
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
import tokenize
import typing
from pathlib import Path
from typing import Any, NamedTuple

ROOT = Path(__file__).resolve().parent.parent
CONFIG_PAGE = "reference/configuration.md"


class Row(NamedTuple):
    """One configuration key of the reference."""

    key: str
    type: str
    default: str
    unit: str
    meaning: str


class Node(NamedTuple):
    """One table of the reference: a config node (a dataclass) under its dotted prefix."""

    title: str
    prefix: str
    cls: type
    rows: list[Row]


# ---------------------------------------------------------------------------------------------
# What the docstrings and the declarations say about each field


def attribute_docs(cls: type) -> dict[str, str]:
    """The ``Attributes:`` entries of ``cls`` and its bases (the nearest class wins), one line each.

    A line at an entry's indentation that is not ``name: description`` continues that entry.
    """
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        docs.update(_attributes_section(klass.__dict__.get("__doc__") or ""))
    return docs


def _attributes_section(doc: str) -> dict[str, str]:
    lines = inspect.cleandoc(doc).splitlines()
    entries: dict[str, list[str]] = {}
    inside, indent, current, entry_depth = False, 0, None, 0
    for line in lines:
        if not inside:
            inside = line.strip() == "Attributes:"
            indent = len(line) - len(line.lstrip()) if inside else 0
            continue
        if not line.strip():
            continue
        depth = len(line) - len(line.lstrip())
        if depth <= indent:  # the next section (or the end of this one)
            break
        m = re.match(r"\s*([A-Za-z_]\w*)\s*(\([^)]*\))?:\s*(.*)", line)
        if m and (current is None or depth <= entry_depth):
            current, entry_depth = m.group(1), depth
            entries[current] = [m.group(3)]
        elif current is not None:
            entries[current].append(line.strip())
    return {k: " ".join(v).strip() for k, v in entries.items()}


def field_comments(cls: type) -> dict[str, str]:
    """The ``#`` comments on each field's declaration (and on the lines just above it)."""
    comments: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass) or klass.__module__ == "builtins":
            continue
        try:
            source = textwrap.dedent(inspect.getsource(klass))
        except (OSError, TypeError):
            continue
        by_line: dict[int, str] = {}
        for tok in tokenize.generate_tokens(io.StringIO(source).readline):
            if tok.type == tokenize.COMMENT:
                by_line[tok.start[0]] = tok.string.lstrip("#").strip()
        body = ast.parse(source).body[0]
        assert isinstance(body, ast.ClassDef)
        previous_end = body.lineno
        for stmt in body.body:
            if isinstance(stmt, ast.AnnAssign) and isinstance(stmt.target, ast.Name):
                start = stmt.lineno
                while start - 1 > previous_end and (start - 1) in by_line:
                    start -= 1
                end = stmt.end_lineno or stmt.lineno
                text = "; ".join(by_line[i] for i in range(start, end + 1) if i in by_line)
                if text:
                    comments[stmt.target.id] = text
            previous_end = stmt.end_lineno or stmt.lineno
    return comments


def _unit(comment: str, doc: str) -> tuple[str, str]:
    """The unit (from the comment, else the docstring) and what the comment says besides."""
    m = re.match(r"\s*\[([^\]]*)\]\s*[;,]?\s*(.*)", comment)
    if m:
        return m.group(1).strip(), m.group(2).strip()
    m = re.search(r"\[([^\]]*)\]", doc)
    return (m.group(1).strip() if m else ""), comment.strip()


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def scale_note(power: int) -> str:
    """How a ``scaled(power)`` field converts to the scene: ``× scenario.scale`` etc."""
    if not power:
        return ""
    exponent = "" if power == 1 else str(power).translate(_SUPERSCRIPT)
    return f"× `scenario.scale`{exponent}"


def format_value(value: Any) -> str:
    """A default as one would write it in YAML or on the command line."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, str):
        return value if value else '""'
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        inner = ", ".join(
            f"{f.name}: {format_value(getattr(value, f.name))}" for f in dataclasses.fields(value)
        )
        return "{" + inner + "}"
    return str(value)


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def _clean(text: str) -> str:
    """Docstring text for a table cell: Sphinx roles as code, ``literals`` as code, no pipes."""
    text = re.sub(r":(?:mod|func|class|meth|data|attr|obj):`~?([^`]+)`", r"`\1`", text)
    text = re.sub(r"``([^`]+)``", r"`\1`", text)
    text = text.replace("||", "‖")  # a norm; a table cell cannot hold a pipe inside code
    parts = text.split("`")  # odd parts are code spans, where an escaped pipe shows its backslash
    parts = [p.replace("|", "∣" if i % 2 else "\\|") for i, p in enumerate(parts)]
    return "`".join(parts).strip()


def _limits(f: dataclasses.Field, integer: bool) -> str:
    declared = f.metadata.get("limits") if f.metadata else None
    return declared.describe(integer) if declared is not None else ""


def field_row(cls: type, f: dataclasses.Field, prefix: str, nested: set[type]) -> Row:
    """The row of field ``f`` of dataclass ``cls``.

    A field whose type is in ``nested`` links to its own table instead of showing its default.
    """
    from amex.core.scaling import SCALE_KEY

    default = _default(f)
    doc = attribute_docs(cls).get(f.name, "")
    if not doc and dataclasses.is_dataclass(default):
        doc = _first_line(type(default).__doc__)
    unit, note = _unit(field_comments(cls).get(f.name, ""), doc)
    if unit:
        doc = doc.replace(f" [{unit}]", "", 1)
    meaning = _clean(doc)
    if note and not _said(note, doc):
        note = _clean(note)
        note = note if note.startswith("(") and note.endswith(")") else f"({note})"
        meaning = f"{meaning} {note}" if meaning else note
    valid = _limits(f, isinstance(default, int))
    if valid:
        meaning += f" Valid: {valid}."
    power = int(f.metadata.get(SCALE_KEY, 0)) if f.metadata else 0
    unit = ", ".join(part for part in (unit, scale_note(power)) if part)
    type_name = _type_name(typing.get_type_hints(cls).get(f.name, Any))
    key = prefix + f.name
    if dataclasses.is_dataclass(default) and type(default) in nested:
        shown = f"see [`{key}`](#{_anchor(key)})"
    elif dataclasses.is_dataclass(default):
        shown = f"`{format_value(default)}`"
        type_name = f"[`{type(default).__name__}`](#{_anchor(type(default).__name__)})"
    else:
        shown = "required" if default is dataclasses.MISSING else f"`{format_value(default)}`"
    return Row(f"`{key}`", type_name, shown, unit, meaning)


def node_rows(cls: type, prefix: str, nested: set[type]) -> list[Row]:
    """The rows of the dataclass ``cls``, one per field (see :func:`field_row`)."""
    return [field_row(cls, f, prefix, nested) for f in dataclasses.fields(cls)]


def _said(note: str, doc: str) -> bool:
    """Whether every word of a declaration's comment is in the docstring entry already."""
    words = set(re.findall(r"[a-z]+", doc.lower()))
    return set(re.findall(r"[a-z]+", note.lower())) <= words


def _type_name(hint: Any) -> str:
    if hint is Any:
        return "any"
    if isinstance(hint, type) and not typing.get_args(hint):
        return f"`{hint.__name__}`"
    return f"`{str(hint).replace('typing.', '')}`"


def _anchor(key: str) -> str:
    """The id of a table's heading (``attr_list`` ids: dots become dashes)."""
    return re.sub(r"[^a-z0-9_-]+", "-", key.lower()).strip("-")


# ---------------------------------------------------------------------------------------------
# The page


def builtin_methods() -> dict[str, Any]:
    """The registered methods that amex itself defines (plugins installed here are left out)."""
    from amex.methods import METHODS

    return {
        name: cls for name, cls in sorted(METHODS.items()) if cls.__module__.startswith("amex.")
    }


def config_nodes() -> list[Node]:
    """Every node of the configuration reference, in page order."""
    from amex.experiment.config import RunConfig

    root = RunConfig()
    nested = {
        type(getattr(root, f.name))
        for f in dataclasses.fields(RunConfig)
        if dataclasses.is_dataclass(getattr(root, f.name)) and f.name != "method"
    }
    rows = node_rows(RunConfig, "", nested)
    default_method = group_defaults().get("method", "")
    rows = [
        Row(
            "`method`",
            "config group",
            f"`{default_method}`",
            "",
            "the method and its parameters: `method=<name>` picks one of the `method=` tables "
            "below, `method.<field>=...` overrides one of its fields.",
        )
        if r.key == "`method`"
        else r
        for r in rows
    ]
    nodes = [Node("Top level", "", RunConfig, rows)]
    for f in dataclasses.fields(RunConfig):
        value = getattr(root, f.name)
        if f.name != "method" and type(value) in nested:
            cls = type(value)
            rows = node_rows(cls, f"{f.name}.", set())
            nodes.append(Node(f"`{f.name}`", f"{f.name}.", cls, rows))
    for name, method in builtin_methods().items():
        cls = method.config_class
        nodes.append(Node(f"`method={name}`", "method.", cls, node_rows(cls, "method.", set())))
    return nodes


def group_defaults() -> dict[str, str]:
    """The config groups ``conf/config.yaml`` picks by default (``method: amex``, ...)."""
    import yaml

    defaults = yaml.safe_load((ROOT / "conf" / "config.yaml").read_text()).get("defaults", [])
    return {
        k: str(v)
        for d in defaults
        if isinstance(d, dict)
        for k, v in d.items()
        if "/" not in k and v is not None
    }


#: The config groups of ``conf/`` that users pick from, in page order.
GROUPS = ("method", "robot", "experiment", "study", "hydra/launcher")


def _summary(path: Path) -> str:
    """The first sentence of a YAML file's leading comment (``# @package`` skipped)."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        text = line[1:]
        if text.strip().startswith("@package") or not text.strip():
            continue
        if text.startswith("   "):  # an indented command: the prose has ended
            break
        lines.append(text.strip())
    prose = " ".join(lines)
    m = re.match(r"(.+?\.)(?=\s+[A-Z(`]|\s*$)", prose)
    sentence = m.group(1) if m else prose
    return _clean(sentence[:-1] + "." if sentence.endswith(":") else sentence)


def config_groups() -> list[tuple[str, str, str]]:
    """``(group, option, summary)`` for every YAML option of :data:`GROUPS` under ``conf/``."""
    out = []
    for group in GROUPS:
        base = ROOT / "conf" / group
        for path in sorted(base.rglob("*.yaml")):
            option = path.relative_to(base).with_suffix("").as_posix()
            out.append((group, option, _summary(path)))
    return out


def _gain_types(nodes: list[Node]) -> list[type]:
    """The small value types (``PD``) that appear inline in the tables."""
    seen: dict[str, type] = {}
    for node in nodes:
        for f in dataclasses.fields(node.cls):
            if node.prefix == "" and f.name == "method":  # its own tables, one per method
                continue
            value = _default(f)
            inline = dataclasses.is_dataclass(value) and not isinstance(value, type)
            if inline and not any(n.cls is type(value) for n in nodes):
                seen.setdefault(type(value).__name__, type(value))
    return [seen[k] for k in sorted(seen)]


def _table(rows: list[Row]) -> list[str]:
    lines = ["| key | type | default | unit | meaning |", "|---|---|---|---|---|"]
    lines += [f"| {r.key} | {r.type} | {r.default} | {r.unit} | {r.meaning} |" for r in rows]
    return lines


def _first_line(doc: str | None) -> str:
    return _clean(inspect.cleandoc(doc or "").split("\n\n")[0].replace("\n", " "))


def _described(cls: type) -> str:
    """The summary line of ``cls``, then its dotted name in parentheses."""
    name = f"{cls.__module__}.{cls.__qualname__}"
    return f"{_first_line(cls.__doc__).rstrip('.')} (`{name}`)."


def config_reference() -> str:
    """The configuration reference page, as Markdown."""
    nodes = config_nodes()
    out = [
        "# Configuration reference",
        "",
        "Generated when the site is built, from the config dataclasses themselves "
        "(`docs/hooks.py`): every key `amex-run` accepts, its type, its default, its unit and "
        "what it means, as the code declares them. The defaults are the dataclasses'; the "
        "`robot=` and `experiment=` files of `conf/` change some of them (for example "
        "`scenario.scale`, see [Configuration](../configuration.md)). Override any key on the "
        "command line: `amex-run scenario.scale=0.25 method.rate_max=3`.",
        "",
        "A unit followed by × `scenario.scale` marks a length (or a weight) stated in the "
        "original experiment's scene units: the run multiplies it by the scale once, in "
        "`amex/core/scaling.py` (a power such as ⁻² divides by the squared scale). Numbers "
        "without declared limits must be finite and, unless their default is negative, "
        "non-negative (`amex/core/schema.py`).",
        "",
    ]
    for node in nodes:
        anchor = _anchor(node.prefix[:-1]) if node.prefix and node.prefix != "method." else ""
        if node.title.startswith("`method="):
            anchor = _anchor("method-" + node.title.strip("`").split("=", 1)[1])
        elif not node.prefix:
            anchor = "top-level"
        out += [f"## {node.title} {{#{anchor}}}", ""]
        out += [_described(node.cls), ""]
        out += _table(node.rows)
        out.append("")
    chosen = group_defaults()
    out += [
        "## Config groups {#config-groups}",
        "",
        "The options of each config group are the YAML files under `conf/<group>/` (listed here "
        "from the files, with the first sentence of their leading comment). A `method` option "
        "fills `method.*`; `robot`, `experiment` and `study` options are `# @package _global_` "
        "files that set keys anywhere in the tables above. Defaults of `conf/config.yaml`: "
        + ", ".join(f"`{k}={v}`" for k, v in chosen.items())
        + ".",
        "",
        "| group | option | what it is |",
        "|---|---|---|",
    ]
    out += [f"| `{g}` | `{g}={o}` | {text} |" for g, o, text in config_groups()]
    out.append("")
    for cls in _gain_types(nodes):
        out += [f"## `{cls.__name__}` {{#{_anchor(cls.__name__)}}}", ""]
        out += [
            f"{_described(cls)} Written inline, e.g. "
            f"`controller.col={{kp: 2500, kd: 100, weight: 10}}`, or one field at a time, "
            f"`controller.col.kp=2500`.",
            "",
        ]
        out += _table(node_rows(cls, "", set()))
        out.append("")
    return "\n".join(out)


def on_files(files: Any, config: Any) -> Any:
    """MkDocs event: add the generated configuration reference to the site's files."""
    from mkdocs.structure.files import File

    files.append(File.generated(config, CONFIG_PAGE, content=config_reference()))
    return files


# ---------------------------------------------------------------------------------------------
# Results tables: analysis commands over committed runs


class Table(NamedTuple):
    """A generated file under docs/generated/: the command that writes it into ``--out``."""

    path: str  # relative to the repository root
    argv: tuple[str, ...]  # ``python -m ...`` arguments, run from the repository root


#: The ablation's steps committed under docs/data/runs/ablation/ (conf/experiment/ablation/).
ABLATION_STEPS = ("1_harness", "2_controller", "3_methods", "4_dynamic")

TABLES: tuple[Table, ...] = (
    Table(
        "docs/generated/paper/fig5.md",
        ("analysis.table", "docs/data/runs/paper"),
    ),
    Table(
        "docs/generated/original/compare.md",
        (
            "analysis.compare",
            "original=docs/data/runs/paper_original",
            "ours=docs/data/runs/paper",
        ),
    ),
    Table("docs/generated/seeds/fig5.md", ("analysis.table", "docs/data/runs/seeds")),
    Table(
        "docs/generated/original_seeds/fig5.md",
        ("analysis.table", "docs/data/runs/original_seeds"),
    ),
    Table(
        "docs/generated/ablation/compare.md",
        (
            "analysis.compare",
            "original=docs/data/runs/paper_original",
            *(f"{step}=docs/data/runs/ablation/{step}" for step in ABLATION_STEPS),
            "ours=docs/data/runs/paper",
        ),
    ),
    Table(
        "docs/generated/compute/compute.md",
        (
            "analysis.compute",
            "beside_sweep=docs/data/runs/compute/beside_sweep",
            "loaded=docs/data/runs/compute/loaded",
        ),
    ),
    *(
        Table(
            f"docs/generated/baselines/{robot}.md",
            ("analysis.baselines", "docs/data/runs/baselines", "--robot", robot),
        )
        for robot in ("panda", "ur5", "chain7")
    ),
    Table(
        "docs/generated/baselines/tuning.md",
        (
            "analysis.baselines",
            "--tuning",
            *(f"docs/data/runs/tuning/{m}" for m in ("rmpflow", "dmp_avoid", "cbf_ik", "amex_cbf")),
        ),
    ),
)


def write_table(table: Table, out_dir: Path) -> Path:
    """Run ``table``'s command with ``--out out_dir``; the path of the file it wrote there."""
    done = subprocess.run(
        [sys.executable, "-m", *table.argv, "--out", str(out_dir)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise RuntimeError(f"python -m {' '.join(table.argv)} failed:\n{done.stderr}")
    return out_dir / Path(table.path).name


def regenerate() -> None:
    """Write every file of :data:`TABLES` again (``make docs-tables``)."""
    for table in TABLES:
        with tempfile.TemporaryDirectory() as tmp:
            written = write_table(table, Path(tmp))
            target = ROOT / table.path
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(written, target)
            print(f"wrote {table.path}")


if __name__ == "__main__":
    regenerate()
