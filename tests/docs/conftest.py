"""Fixtures of the documentation tests."""

from __future__ import annotations

import pytest
from docs_modules import load


@pytest.fixture(scope="session")
def hooks():
    return load("hooks")


@pytest.fixture(scope="session")
def griffe_roles():
    pytest.importorskip("griffe")
    return load("griffe_roles")
