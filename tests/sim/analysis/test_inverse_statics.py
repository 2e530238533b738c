"""Inverse statics (sim.analysis.inverse.reach): the natural curvature found puts the tip on a reachable target at
equilibrium (checked by an independent static solve), in 3-D and 2-D, with every env its own target; a target out
of reach ends at the bound, not converged, with no NaN; bad requests are refused by name."""
from __future__ import annotations

import numpy as np
import pytest

from sim import build_model, load_scene
from sim.analysis.inverse import ReachError, reach
from sim.analysis.static import solve_static
from sim.step import Simulator
from sim.support.assets import asset_path


def equilibrium_tip(spec, kappa_bar):
    """The tip at equilibrium under ``kappa_bar`` (B, N, 2), by a static solve of its own."""
    sim = Simulator(build_model(spec), envs=kappa_bar.shape[0])
    state, ctrl = sim.reset(), sim.make_control()
    ctrl.kappa_bar[...] = kappa_bar
    res = solve_static(spec, state, ctrl, check_stability=False)
    assert res.converged.all()
    return np.asarray(state.node_pos)[:, -1, :]


@pytest.mark.parametrize("scene", ["arm.toml", "arm_2d.toml"])
def test_reachable_targets_are_reached_at_equilibrium(scene):
    spec = load_scene(asset_path(f"scenes/{scene}"))
    targets = np.array([[0.3, 0.0, 0.85], [-0.2, 0.25, 0.8], [0.5, 0.0, 0.6]])
    if "2d" in scene:
        targets[:, 1] = 0.0
    res = reach(spec, targets, bound=0.3, tol=1e-6)
    assert res.converged.all() and np.all(res.error <= 1e-6), res.error
    assert np.abs(res.kappa_bar).max() <= 0.3
    tip = equilibrium_tip(spec, res.kappa_bar)
    np.testing.assert_allclose(tip, targets, atol=1e-5)


def test_a_target_out_of_reach_ends_at_the_bound():
    spec = load_scene(asset_path("scenes/arm.toml"))
    res = reach(spec, [[0.9, 0.0, 0.2]], bound=0.05, max_iterations=15)
    assert not res.converged[0] and np.isfinite(res.error[0]) and res.error[0] > 0.1
    assert np.all(np.isfinite(res.kappa_bar)) and np.isclose(np.abs(res.kappa_bar).max(), 0.05)


def test_bad_requests_are_refused():
    spec = load_scene(asset_path("scenes/arm.toml"))
    with pytest.raises(ReachError, match="targets must be finite"):
        reach(spec, [[0.1, np.nan, 0.5]])
    with pytest.raises(ReachError, match="interior nodes"):
        reach(spec, [[0.1, 0.0, 0.5]], nodes=[0, 5])
    with pytest.raises(ReachError, match="contact"):
        reach(load_scene(asset_path("scenes/default.toml")), [[0.1, 0.0, 0.5]])
