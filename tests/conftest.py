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
