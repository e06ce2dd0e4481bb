"""The Python snippets of the README and the pages run as written (on a straight-line reference)."""

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = ("README.md", "docs/api/index.md", "docs/methods/index.md")


def _method_snippets() -> list[tuple[str, str]]:
    """``(page, code)`` of every python block that drives a method with arrays."""
    found = []
    for page in PAGES:
        for code in re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), re.S):
            if "from amex.methods import" in code and "update(" in code:
                found.append((page, code))
    return found


def test_the_pages_have_method_snippets():
    assert {page for page, _ in _method_snippets()} == set(PAGES)


@pytest.mark.parametrize(("page", "code"), _method_snippets(), ids=lambda v: str(v)[:24])
def test_a_method_snippet_runs(page, code):
    reference = np.linspace([0.4, 0.0, 0.5], [0.6, 0.2, 0.4], 401)
    names = {"reference": reference, "y": reference[0].copy(), "g": np.array([0.6, 0.25, 0.4])}
    exec(compile(code, page, "exec"), names)  # noqa: S102 (our own documentation)
    target = names["target"]
    assert np.all(np.isfinite(target[0])) and np.all(np.isfinite(target[1]))
