"""The kinematic simulator stand-ins of the fast tests (tests/policies/policies_fake_sim.py,
tests/recordings/recordings_fake_sim.py) follow the real ``sim`` API: their states are real ``sim.State``
objects, the methods the tasks call have the real signatures, and the recordings fake reports every
``StepStats`` field. A change of the real API therefore fails here instead of leaving the fakes behind."""
from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

from sim.state import State, StepStats
from sim.step import Simulator
from tests.policies import policies_fake_sim
from tests.recordings import recordings_fake_sim

FAKES = [policies_fake_sim.FakeSim, recordings_fake_sim.FakeSim]
CALLED_BY_TASKS = ("reset", "reset_envs", "step", "make_control", "material_frames")


@pytest.mark.parametrize("fake", FAKES)
@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_fake_state_is_a_real_state(fake, mode):
    sim = fake(mode, 3)
    state = sim.reset()
    assert type(state) is State
    nd = 2 if mode == "2d" else 4
    assert state.dof.shape == state.dof_vel.shape == (3, 21, nd)
    assert state.edge_tangent.shape == state.edge_ref_d1.shape == (3, 20, 3)
    assert state.node_ref_twist.shape == (3, 21) and state.time.shape == state.failed.shape == (3,)
    ctrl = sim.make_control()
    ctrl.kappa_bar[:, 1:-1, 0] = 0.01
    sim.step(state, ctrl)
    assert type(state) is State and state.node_pos.shape == (3, 21, 3)
    assert np.allclose(np.linalg.norm(state.edge_tangent, axis=-1), 1.0)
    m1, m2, t = sim.material_frames(state)
    assert m1.shape == m2.shape == t.shape == (3, 20, 3)
    sim.reset_envs(state, ctrl, np.array([True, False, False]))
    assert np.all(ctrl.kappa_bar[0] == 0) and np.any(ctrl.kappa_bar[1] != 0)


@pytest.mark.parametrize("fake", FAKES)
@pytest.mark.parametrize("name", CALLED_BY_TASKS)
def test_fake_methods_have_the_real_signatures(fake, name):
    real = list(inspect.signature(getattr(Simulator, name)).parameters)
    mine = list(inspect.signature(getattr(fake, name)).parameters)
    assert mine == real, f"{fake.__module__}.{name}{mine} differs from Simulator.{name}{real}"


def test_recordings_fake_reports_every_step_stats_field():
    sim = recordings_fake_sim.FakeSim("3d", 2, obstacles=1)
    state = sim.reset()
    stats = sim.step(state, sim.make_control())
    missing = [f.name for f in dataclasses.fields(StepStats) if not hasattr(stats, f.name)]
    assert not missing, f"the recordings fake's StepStats lacks {missing}"
