"""Fixtures for the policies tests. ``fake_sim`` swaps the simulator for a kinematic stand-in (fast,
no numba compile) for tests of env structure; tests of behaviour use the real simulator."""
from __future__ import annotations

import pytest


@pytest.fixture
def fake_sim(monkeypatch):
    from policies.tasks import scenes
    from tests.policies.policies_fake_sim import fake_make_simulator, fake_set_env_capsules

    monkeypatch.setattr(scenes, "make_simulator", fake_make_simulator)
    monkeypatch.setattr(scenes, "set_env_capsules", fake_set_env_capsules)
    yield
