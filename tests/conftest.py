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


def process_group(nodeid: str) -> str:
    """Which tests run together on one process when the suite runs on several (``make test``, pytest-xdist):
    every test of tests/workbench but the soak on one, in the order of a run in one process (they share one
    Chromium, one page and one workbench session, as they do there), and each other file's tests on one, so a
    module's fixtures are built once."""
    path = nodeid.split("::")[0]
    if path.startswith("tests/workbench/") and not path.endswith("/test_soak.py"):
        return "tests/workbench"
    return path


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    from xdist.scheduler import LoadScopeScheduling

    class ByGroup(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return process_group(nodeid)

    return ByGroup(config, log)
