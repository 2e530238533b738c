"""Simulator API: control validation, control helpers, reset_envs, material frames, State properties."""
from __future__ import annotations

import numpy as np
import pytest

from sim import Simulator, build_model, load_scene


@pytest.fixture
def arm(scenes_dir):
    sim = Simulator(build_model(load_scene(scenes_dir / "arm.toml")), envs=3)
    return sim, sim.reset(), sim.make_control()


def test_bad_controls_raise_naming_the_field(arm):
    sim, state, ctrl = arm
    ctrl.kappa_bar[1, 5, 0] = np.nan
    with pytest.raises(ValueError, match="ctrl.kappa_bar"):
        sim.step(state, ctrl)
    ctrl.kappa_bar[1, 5, 0] = 0.0
    ctrl.tau_bar[0, 3] = np.inf
    with pytest.raises(ValueError, match="ctrl.tau_bar"):
        sim.step(state, ctrl)
    ctrl.tau_bar = np.zeros((3, 20))
    with pytest.raises(ValueError, match="ctrl.tau_bar.*shape"):
        sim.step(state, ctrl)
    state.dof = state.dof[:, :, :3].copy()
    with pytest.raises(ValueError, match="state.dof"):
        sim.step(state, sim.make_control())


def test_control_helpers_and_increments_act_in_the_current_step(arm):
    sim, state, ctrl = arm
    sim.set_natural_curvature(ctrl, [0.05, 0.0], nodes=slice(1, -1), envs=[1])
    sim.add_natural_curvature(ctrl, [0.0, 0.02], nodes=slice(1, -1), envs=2)
    sim.add_natural_twist(ctrl, 0.01, nodes=slice(1, -1), envs=2)
    assert np.all(ctrl.kappa_bar[1, 1:-1, 0] == 0.05) and np.all(ctrl.kappa_bar[0] == 0)
    st = sim.step(state, ctrl)
    tip = state.node_pos[:, -1]
    assert tip[1, 0] < -1e-3 and abs(tip[0, 0]) < 1e-12       # env 1 bent toward −x in this very step
    assert tip[2, 1] < -1e-4                                    # κ̄2 > 0 bends the upright arm toward −y
    assert st.energy_bend[1] > 0 and st.energy_twist[2] > 0 and np.all(st.substeps == 1)


def test_reset_envs_and_material_frames(arm):
    sim, state, ctrl = arm
    ctrl.kappa_bar[:, 1:-1, :] = 0.05
    ctrl.tau_bar[:, 1:-1] = 0.02
    for _ in range(5):
        sim.step(state, ctrl)
    m1, m2, t = sim.material_frames(state)
    for a, b in ((m1, m2), (m1, t), (m2, t)):
        assert np.abs((a * b).sum(-1)).max() < 1e-12
    assert np.abs(np.linalg.norm(m1, axis=-1) - 1).max() < 1e-12
    assert np.allclose(np.cross(m1, m2), t, atol=1e-12)
    before = state.copy()
    sim.reset_envs(state, ctrl, np.array([False, True, False]))
    fresh = sim.reset()
    assert np.array_equal(state.dof[1], fresh.dof[1]) and state.time[1] == 0 and np.all(ctrl.kappa_bar[1] == 0)
    assert np.array_equal(state.dof[[0, 2]], before.dof[[0, 2]]) and np.all(ctrl.kappa_bar[0, 1:-1] == 0.05)
    assert state.node_pos.shape == (3, 21, 3) and state.edge_theta.shape == (3, 20)


def test_2d_state_properties(scenes_dir):
    sim = Simulator(build_model(load_scene(scenes_dir / "arm_2d.toml")), envs=2)
    state = sim.reset()
    assert state.dof.shape == (2, 21, 2) and state.node_pos.shape == (2, 21, 3)
    assert np.allclose(state.node_pos[0, :, 2], np.linspace(0, 1, 21))
    assert np.all(state.edge_theta == 0) and state.edge_theta.shape == (2, 20)
