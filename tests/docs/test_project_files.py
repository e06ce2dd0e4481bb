"""The files people look for: the README as a front page, LICENSE, CITATION.cff, CHANGELOG."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

import amex

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def test_the_readme_is_a_short_front_page_with_the_two_setup_commands():
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    assert "make run" in text and "make test" in text
    first_block = text.split("```")[1]  # the set-up commands come first, before any usage
    assert "make run" in first_block and "make test" in first_block


def test_every_relative_link_of_the_readme_exists():
    text = README.read_text()
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if not re.match(r"[a-z]+://", t)]
    assert local, "the README links to the docs pages"
    assert [t for t in local if not (ROOT / t).exists()] == []


def test_the_readme_picture_is_committed_and_small():
    pictures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", README.read_text())
    assert pictures
    for picture in pictures:
        assert (ROOT / picture).stat().st_size < 200_000


def test_the_licence_is_mit_held_by_the_amex_developers():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "the amex developers" in text
    pyproject = (ROOT / "pyproject.toml").read_text()
    assert re.search(r'^license = "MIT"$', pyproject, re.M)


def test_the_citation_file_names_the_software_and_the_paper():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert cff["version"] == amex.__version__ and cff["license"] == "MIT"  # one version
    title = "Reactive Phase and Task Space Adaptation for Robust Motion Execution"
    for paper in (cff["preferred-citation"], *cff["references"]):
        assert paper["title"] == title
        assert [a["family-names"] for a in paper["authors"]] == ["Englert", "Toussaint"]
        assert paper["year"] == 2014 and "IROS" in paper["collection-title"]


def test_the_citation_file_is_valid_for_its_schema():
    cffconvert = pytest.importorskip("cffconvert")  # pip install cffconvert to run this check
    from cffconvert import Citation

    Citation((ROOT / "CITATION.cff").read_text()).validate()
    assert cffconvert


def test_the_changelog_has_this_release_and_the_one_before():
    text = (ROOT / "CHANGELOG.md").read_text()
    versions = re.findall(r"^## \[(\d+\.\d+\.\d+)\]", text, re.M)
    assert versions[:2] == ["0.2.0", "0.1.0"]


def test_site_output_is_ignored_by_git():
    assert "/site/" in (ROOT / ".gitignore").read_text().split()
