"""Shared pytest configuration (keep small). The numba kernels are compiled by `python -m sim.warmup`
(the Makefile runs it first); tests only load them from the cache."""
from __future__ import annotations

import os
from pathlib import Path

# The suite runs on two processes (make test), each with numba's OpenMP threads, on as many cores as a CI machine has:
# threads that spin while they wait keep the other process's threads off the cores (a numba-parallel test took 21 s
# beside a second one and 9 s with passive waiting). Set before numba or torch loads an OpenMP runtime.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

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


def pytest_collection_modifyitems(config, items) -> None:
    """The longest groups first (longest processing time first: the processes end together): tests/workbench,
    then the groups holding a test marked ``long(seconds=…)``, longest first, then the rest in their order. The
    processes take the groups in this order (``pytest_xdist_make_scheduler``)."""
    longest: dict[str, float] = {}
    for item in items:
        mark = item.get_closest_marker("long")
        if mark is not None:
            if "seconds" not in mark.kwargs:
                raise pytest.UsageError(f"{item.nodeid}: write @pytest.mark.long(seconds=…) (about how long it takes)")
            group = process_group(item.nodeid)
            longest[group] = max(longest.get(group, 0.0), float(mark.kwargs["seconds"]))

    def rank(item) -> tuple[int, float]:
        group = process_group(item.nodeid)
        if group == "tests/workbench":
            return 0, 0.0
        return (1, -longest[group]) if group in longest else (2, 0.0)

    items.sort(key=rank)  # stable: each group keeps its order


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    from xdist.scheduler import LoadScopeScheduling

    class ByGroup(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return process_group(nodeid)

    config.option.loadscopereorder = False  # the groups in the collection's order (pytest_collection_modifyitems)
    return ByGroup(config, log)
