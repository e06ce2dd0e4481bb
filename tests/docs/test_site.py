"""The site's configuration: strict link and anchor checks, and the API pages' docstring reading."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]


def _mkdocs_config() -> dict:
    class Loader(yaml.SafeLoader):
        pass

    Loader.add_multi_constructor("tag:yaml.org,2002:python/", lambda *a: None)
    return yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=Loader)


def test_every_link_and_anchor_check_is_on():
    validation = _mkdocs_config()["validation"]
    assert set(validation["nav"].values()) == {"warn"}
    assert validation["links"]["anchors"] == "warn"
    assert validation["links"]["not_found"] == "warn"


def test_a_broken_anchor_fails_the_strict_build(tmp_path):
    pytest.importorskip("mkdocs")
    config = _mkdocs_config()
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "index.md").write_text("# Home\n\n[there](other.md#no-such-anchor)\n")
    (tmp_path / "docs" / "other.md").write_text("# Other\n\n## A heading\n")
    site = {
        "site_name": "check",
        "validation": config["validation"],
        "nav": [{"Home": "index.md"}, {"Other": "other.md"}],
    }
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(site))
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or "mkdocs"
    done = subprocess.run(
        [mkdocs, "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=tmp_path, capture_output=True, text=True,
    )
    assert done.returncode != 0
    assert "does not contain an anchor '#no-such-anchor'" in done.stderr


def test_sphinx_roles_read_as_code(griffe_roles):
    text = "An :class:`~amex.core.types.PD` of :mod:`amex.core.scaling`."
    assert griffe_roles.replace_roles(text) == "An `PD` of `amex.core.scaling`."


def test_a_stray_continuation_line_joins_its_entry(griffe_roles):
    doc = "Attributes:\n    a: one,\n    (continued).\n    b: two.\n\nReturns:\n    x\n    y"
    assert griffe_roles.indent_continuations(doc) == (
        "Attributes:\n    a: one,\n        (continued).\n    b: two.\n\nReturns:\n    x\n    y"
    )
