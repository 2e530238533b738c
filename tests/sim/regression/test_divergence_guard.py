"""Divergence guard (docs/physics.md §6.3): with the paper's 2 accepted-unconverged Newton
iterations, a step whose force residual grows by more than ``[sim] divergence_guard`` (default 10) over its
iterations is retried with 2, 4, 8, 16 sub-steps (the least-bad result kept, never a failure by itself).
Scenario: the paper arm under saturating bang-bang curvature commands (the stress benchmark's generator),
which without the guard drives many envs into an unrecoverable state (flagged failed and frozen)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from benchmarks.stress import curvature_commands
from sim import Simulator, build_model, load_scene

B = 32


def _bang_bang(scene, guard: float):
    spec = load_scene(scene)
    spec = replace(spec, sim=replace(spec.sim, divergence_guard=guard))
    sim = Simulator(build_model(spec), envs=B)
    state, ctrl = sim.reset(), sim.make_control()
    retried = 0
    for dk in curvature_commands("bang-bang", envs=B, nodes=sim.model.node_count, control_steps=200):
        for _ in range(2):
            ctrl.kappa_bar += dk / 2
            st = sim.step(state, ctrl)
            retried += int((st.substeps > 1).sum())
            assert np.isfinite(state.dof).all() and np.isfinite(st.residual).all()
    return int(state.failed.sum()), retried


def test_guard_keeps_saturating_commands_from_failing_envs(scenes_dir):
    failed_off, _ = _bang_bang(scenes_dir / "arm.toml", 0.0)
    failed_on, retried_on = _bang_bang(scenes_dir / "arm.toml", 10.0)
    assert failed_off >= 4, f"the scenario should fail envs without the guard, failed {failed_off}/{B}"
    assert failed_on <= failed_off // 4, (failed_on, failed_off)
    assert retried_on > 0  # the retries are visible in StepStats.substeps


def test_guard_never_trips_on_a_gentle_command(scenes_dir):
    """Ordinary commands converge or nearly: no retries, so the paper's setting is unchanged there."""
    sim = Simulator(build_model(load_scene(scenes_dir / "arm.toml")), envs=8)
    state, ctrl = sim.reset(), sim.make_control()
    rng = np.random.default_rng(0)
    for _ in range(100):
        ctrl.kappa_bar[:, 1:-1, :] += 0.002 * rng.standard_normal((8, 1, 2))
        st = sim.step(state, ctrl)
        assert (st.substeps == 1).all() and not st.failed.any()
