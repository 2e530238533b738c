"""Every step of a scene runs the step kernel compiled for it: external forces (a control's node forces, as the
workbench's hand applies them; point loads) change the arguments' values, never their numba types. A new type (a
read-only broadcast view of the gravity row for one env) made numba compile the 3-D step kernel once more, for
minutes, the first time a rod was pulled."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import sim.step as sim_step
from sim import Simulator, build_model, load_scene
from sim.scene.boundary import LoadSpec
from sim.support.assets import asset_path


@pytest.mark.parametrize("envs", [1, 3])
def test_external_forces_use_the_kernel_of_the_plain_step(envs):
    spec = load_scene(asset_path("scenes/arm.toml"))
    plain = Simulator(build_model(spec), envs=envs)
    state, ctrl = plain.reset(), plain.make_control()
    plain.step(state, ctrl)
    compiled = set(sim_step.step_kernel.signatures)

    ctrl.force = np.zeros((envs, plain.model.node_count, 3))
    ctrl.force[:, -1, 2] = 0.5
    plain.step(state, ctrl)
    loaded = Simulator(build_model(dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(0.0, 0.0, -1.0)),))),
                       envs=envs)
    s2 = loaded.reset()
    loaded.step(s2, loaded.make_control())
    assert set(sim_step.step_kernel.signatures) == compiled
    assert np.isfinite(state.dof).all() and np.isfinite(s2.dof).all()
