"""Griffe extension for the API pages: amex's docstrings read as the source means them.

* amex's docstrings name other objects the Sphinx way (``:class:`~amex.core.types.PD```), which
  Markdown would print as ``:class:`` followed by the name. They are shown as code, the short name
  when the role starts with ``~``.
* In a Google section (``Attributes:``, ``Args:``, ...), a line at the entries' indentation that
  is not ``name: description`` continues the entry above it (a continuation line that lost its
  indentation). Griffe would report it and drop it; it is indented instead, which is how
  ``docs/hooks.py`` reads the same sections.

The docstrings in the sources stay as they are.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:mod|func|class|meth|data|attr|obj|exc|const):`(~?)([^`]+)`")


def _as_code(match: re.Match[str]) -> str:
    short, target = match.groups()
    return f"`{target.rsplit('.', 1)[-1] if short else target}`"


def replace_roles(text: str) -> str:
    """``text`` with every Sphinx role as inline code."""
    return ROLE.sub(_as_code, text)


#: Google sections whose entries are all ``name: description`` (Returns and Raises are not).
SECTION = re.compile(r"^(\s*)(Args|Arguments|Attributes|Parameters|Other Parameters):\s*$")
ENTRY = re.compile(r"^\s*[*]{0,2}[A-Za-z_]\w*\s*(\([^)]*\))?:")
HEADING = re.compile(r"^\s*[A-Z][A-Za-z ]*:\s*$")


def indent_continuations(text: str) -> str:
    """``text`` with stray continuation lines of Google sections indented under their entry."""
    lines = text.split("\n")
    section: int | None = None  # indentation of the current section's heading
    entries: int | None = None  # indentation of its entries
    for i, line in enumerate(lines):
        depth = len(line) - len(line.lstrip())
        if m := SECTION.match(line):
            section, entries = len(m.group(1)), None
        elif section is None or not line.strip():
            continue
        elif depth <= section or HEADING.match(line):
            section = entries = None
        elif entries is None:
            entries = depth
        elif depth == entries and not ENTRY.match(line):
            lines[i] = "    " + line
    return "\n".join(lines)


class SphinxRoles(griffe.Extension):
    """Rewrite the roles in every docstring once the package is loaded."""

    def on_object(self, *, obj: Any, loader: Any, **kwargs: Any) -> None:
        """Griffe event: one object of the tree, with its docstring."""
        if obj.docstring is not None:
            obj.docstring.value = indent_continuations(replace_roles(obj.docstring.value))
