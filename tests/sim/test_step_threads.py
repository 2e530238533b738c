"""The step kernel runs on at most one numba thread per chunk of envs (sim.kernels.batch.CHUNK): a single env does
not keep a second core busy waiting, and the caller's thread setting is restored after the step."""
from __future__ import annotations

import threading

import numba
import numpy as np
import pytest

import sim.step as sim_step
from sim import Simulator, build_model, load_scene
from sim.kernels.batch import CHUNK
from sim.support.assets import asset_path


@pytest.mark.parametrize("envs", [1, CHUNK, CHUNK + 1, 4 * CHUNK])
def test_step_uses_at_most_one_thread_per_chunk_and_restores_the_setting(envs, monkeypatch):
    sim = Simulator(build_model(load_scene(asset_path("scenes/arm.toml"))), envs=envs)
    state, ctrl = sim.reset(), sim.make_control()
    ctrl.kappa_bar[:, 1:-1, 0] = 0.02
    seen = []
    kernel = sim_step.step_kernel
    me = threading.get_ident()

    def spy(*args):
        if threading.get_ident() == me:  # a workbench session of an earlier test may still step in its own thread
            seen.append(numba.get_num_threads())
        return kernel(*args)

    monkeypatch.setattr(sim_step, "step_kernel", spy)
    before = numba.get_num_threads()
    stats = sim.step(state, ctrl)
    assert numba.get_num_threads() == before
    chunks = -(-envs // CHUNK)
    assert seen == [min(before, chunks)]
    assert not stats.failed.any() and np.isfinite(state.dof).all()


def test_thread_count_does_not_change_the_result():
    """One env stepped with the thread cap and a batch whose first env is the same: the same bits."""
    model = build_model(load_scene(asset_path("scenes/arm.toml")))
    one, many = Simulator(model, envs=1), Simulator(model, envs=3 * CHUNK)
    s1, sb = one.reset(), many.reset()
    c1, cb = one.make_control(), many.make_control()
    c1.kappa_bar[:, 1:-1, 0] = cb.kappa_bar[:, 1:-1, 0] = 0.05
    for _ in range(10):
        one.step(s1, c1)
        many.step(sb, cb)
    assert np.array_equal(s1.dof[0], sb.dof[0]) and np.array_equal(s1.dof_vel[0], sb.dof_vel[0])
