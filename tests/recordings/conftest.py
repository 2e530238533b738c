"""Fixtures for the recording tests: the rerun CLI (analytics off once), a verify helper, and a
kinematic fake simulator for the task-probe tests (no numba compile)."""
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


@pytest.fixture
def fake_task_sim(monkeypatch):
    """Swap the task cores' simulator for recordings_fake_sim.FakeSim (with contacts and full StepStats)."""
    from policies.tasks import scenes
    from tests.recordings.recordings_fake_sim import fake_make_simulator, fake_set_env_capsules

    monkeypatch.setattr(scenes, "make_simulator", fake_make_simulator)
    monkeypatch.setattr(scenes, "set_env_capsules", fake_set_env_capsules)
    yield
