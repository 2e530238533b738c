"""Shared pytest configuration (keep small). The numba kernels are compiled by `python -m sim.warmup`
(the Makefile runs it first); tests only load them from the cache."""
from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "assets" / "scenes"


@pytest.fixture
def scenes_dir() -> Path:
    """assets/scenes of the repository."""
    return SCENES


def pytest_collection_modifyitems(config, items) -> None:
    """Which tests run together when the suite runs on several processes (``make test``: pytest-xdist with
    ``--dist loadgroup``): a file's tests on one process, in their order, so its module fixtures are built once;
    and every test that drives the session's Chromium (the ``browser`` fixture) on one process, in the order of
    a run in one process, so those tests share one browser and one page as they do there."""
    for item in items:
        group = "browser" if "browser" in getattr(item, "fixturenames", ()) else item.nodeid.split("::")[0]
        item.add_marker(pytest.mark.xdist_group(group))
