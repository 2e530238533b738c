"""Simulator.set_env_models: each env of one batch with its own masses, stiffnesses, damping and gravity steps to
the same bits as its model alone, and what the envs must share is refused by name."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim import Simulator, build_model
from tests.helpers.rodspec import make_spec, with_sim


def _variants(mode: str):
    base = make_spec(nodes=9, length=0.5, radius=0.01, E=1e6, dt=0.01, gravity=(0.0, 0.0, -9.8), damping=0.2,
                     mode=mode, direction=(0.6, 0.0, 0.8))
    rod = base.rods[0]
    return [base,
            dataclasses.replace(base, rods=(dataclasses.replace(rod, youngs_modulus=3e6, density=700.0),)),
            with_sim(dataclasses.replace(base, rods=(dataclasses.replace(rod, radius=0.013, poisson_ratio=0.3),)),
                     damping=1.5, gravity=(0.5, 0.0, -8.0))]


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_a_batch_of_models_steps_as_each_model_alone(mode):
    specs = _variants(mode)
    models = [build_model(s) for s in specs]
    sim = Simulator(models[0], len(models))
    sim.set_env_models(models)
    state = sim.reset()
    ctrl = sim.make_control()
    ctrl.kappa_bar[:, 4, 0] = 0.3  # a bend commanded at one node
    alone = []
    for m in models:
        s1 = Simulator(m, 1)
        st1, c1 = s1.reset(), s1.make_control()
        c1.kappa_bar[:, 4, 0] = 0.3
        alone.append((s1, st1, c1))
    for _ in range(30):
        sim.step(state, ctrl)
        for s1, st1, c1 in alone:
            s1.step(st1, c1)
    for e, (_, st1, _) in enumerate(alone):
        assert np.array_equal(state.dof[e], st1.dof[0]), e
        assert np.array_equal(state.dof_vel[e], st1.dof_vel[0]), e
    # the variants move apart (the test would pass trivially if they stepped alike)
    assert np.abs(state.dof[1] - state.dof[0]).max() > 1e-3 and np.abs(state.dof[2] - state.dof[0]).max() > 1e-3


def test_what_the_envs_share_is_refused_by_name():
    base, other, _ = _variants("3d")
    m0 = build_model(base)
    sim = Simulator(m0, 2)
    with pytest.raises(ValueError, match="expected 2 models"):
        sim.set_env_models([m0])
    longer = dataclasses.replace(base, rods=(dataclasses.replace(base.rods[0], length=0.6),))
    with pytest.raises(ValueError, match="differ in rest_len"):
        sim.set_env_models([m0, build_model(longer)])
    with pytest.raises(ValueError, match="step parameter dt"):
        sim.set_env_models([m0, build_model(with_sim(other, dt=0.02))])
    fewer = dataclasses.replace(base, rods=(dataclasses.replace(base.rods[0], nodes=7),))
    with pytest.raises(ValueError, match="7 nodes"):
        sim.set_env_models([m0, build_model(fewer)])
