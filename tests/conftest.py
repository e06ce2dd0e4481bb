"""Shared fixtures: the real robot, and a per-session plan cache in a temporary directory."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("OMP_NUM_THREADS", "1")


@pytest.fixture(scope="session", autouse=True)
def _plan_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Keep test runs from reading or writing the user's plan cache."""
    if "AMEX_CACHE_DIR" not in os.environ:
        os.environ["AMEX_CACHE_DIR"] = str(tmp_path_factory.mktemp("amex_cache"))


@pytest.fixture(scope="session")
def robot():
    from amex.robot import load_robot

    return load_robot()
