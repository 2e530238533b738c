"""Fixtures for the recording tests: the rerun CLI (analytics off once) and a verify helper."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def rerun_bin() -> str:
    """Path of the rerun CLI; analytics disabled once per session."""
    from policies.recording.recorder import rerun_cli

    exe = rerun_cli()
    subprocess.run([exe, "analytics", "disable"], capture_output=True, timeout=600)
    return exe


@pytest.fixture(scope="session")
def verify(rerun_bin):
    """verify(path): assert `rerun rrd verify path` exits 0."""
    def _verify(path: str | Path) -> None:
        r = subprocess.run([rerun_bin, "rrd", "verify", str(path)], capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, f"rerun rrd verify {path} failed:\n{r.stdout}\n{r.stderr}"
    return _verify

