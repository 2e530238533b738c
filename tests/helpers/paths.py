"""Paths of the repository for the tests (one place, so a test file can move without counting parents)."""
from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "assets" / "scenes"
