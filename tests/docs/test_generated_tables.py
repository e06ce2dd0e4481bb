"""The results tables the pages include are what the analysis writes for the committed runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from docs_modules import load

ROOT = Path(__file__).resolve().parents[2]
SNIPPET = re.compile(r'^-{1,}8<-{1,} "(docs/generated/[^":]+)(?::(\d+):(\d+))?"\s*$')


def _includes():
    """(page, generated file, first line, last line) of every include of a generated file."""
    found = []
    for page in sorted((ROOT / "docs").rglob("*.md")):
        for line in page.read_text().splitlines():
            m = SNIPPET.match(line.strip())
            if m:
                path, a, b = m.groups()
                found.append((page.relative_to(ROOT).as_posix(), path, a and int(a), b and int(b)))
    return found


def test_the_pages_include_generated_tables():
    assert {path for _, path, _, _ in _includes()} >= {
        "docs/generated/paper/fig5.md",
        "docs/generated/original/compare.md",
        "docs/generated/seeds/fig5.md",  # a seed sweep, pooled
        "docs/generated/compute/compute.md",  # the compute claim on two reruns
    }


@pytest.mark.slow
@pytest.mark.parametrize("table", [t.path for t in load("hooks").TABLES])
def test_a_committed_table_is_what_the_analysis_writes(hooks, table, tmp_path):
    spec = next(t for t in hooks.TABLES if t.path == table)
    written = hooks.write_table(spec, tmp_path)
    committed = (ROOT / table).read_text()
    assert written.read_text() == committed, f"run `make docs-tables` and commit {table}"


@pytest.mark.parametrize("page, path, first, last", _includes())
def test_an_include_is_one_whole_table(page, path, first, last):
    lines = (ROOT / path).read_text().splitlines()
    assert first and last, f"{page} includes all of {path}; include a line range of one table"
    chunk = lines[first - 1 : last]
    assert chunk and all(line.startswith("|") for line in chunk), f"{page}: {path}:{first}:{last}"
    assert re.fullmatch(r"\|(-+\|)+", chunk[1]), f"{page}: line {first + 1} is no table rule"
    before = lines[first - 2] if first >= 2 else ""
    after = lines[last] if last < len(lines) else ""
    assert not before.startswith("|") and not after.startswith("|"), f"{page}: part of a table"


def test_every_generated_file_is_listed_and_included(hooks):
    generated = {p.relative_to(ROOT).as_posix() for p in (ROOT / "docs/generated").rglob("*.md")}
    assert generated == {t.path for t in hooks.TABLES}
    assert generated == {path for _, path, _, _ in _includes()}
