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


def _pose_of(spec, kappa_bar, tau_bar):
    """(tip (B, 3), tip frame (B, 3, 3) columns m1, m2, t) at equilibrium under the given controls."""
    sim = Simulator(build_model(spec), envs=kappa_bar.shape[0])
    state, ctrl = sim.reset(), sim.make_control()
    ctrl.kappa_bar[...] = kappa_bar
    ctrl.tau_bar[...] = tau_bar
    assert solve_static(spec, state, ctrl, check_stability=False).converged.all()
    m1, m2, t = sim.material_frames(state)
    return np.asarray(state.node_pos)[:, -1, :], np.stack([m1[:, -1], m2[:, -1], t[:, -1]], axis=-1)


def test_target_tip_frames_are_reached_with_the_twist():
    """Poses made by the arm itself under known curvature and twist at five control points (bend and twist spread
    over regions, as the 4D IK task's): from the straight arm, reach finds controls whose equilibrium has
    the tip there and the tip frame within 1e-4 rad, checked by an independent static solve; without the target
    frames the same position is reached with the frame far off."""
    spec = load_scene(asset_path("scenes/arm.toml"))
    N = build_model(spec).node_count
    edges = np.linspace(1, N - 1, 6).round().astype(int)  # five regions of interior nodes, each its mean
    basis = np.zeros((N, 5))
    for p, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        basis[lo:hi, p] = 1.0 / (hi - lo)
    rng = np.random.default_rng(3)
    K = rng.uniform(-0.6, 0.6, (3, basis.shape[1], 2))
    T = rng.uniform(-0.8, 0.8, (3, basis.shape[1]))
    kb = np.zeros((3, N, 2))
    kb[:, :, 0], kb[:, :, 1] = K[:, :, 0] @ basis.T, K[:, :, 1] @ basis.T
    tip, R = _pose_of(spec, kb, T @ basis.T)
    res = reach(spec, tip, basis=basis, bound=2.0, orientations=R, tol=1e-6, angle_tol=1e-4)
    assert res.converged.all(), (res.error, res.orientation_error)
    got_tip, got_R = _pose_of(spec, res.kappa_bar, res.tau_bar)
    np.testing.assert_allclose(got_tip, tip, atol=1e-5)
    from sim.analysis.inverse import frame_angle
    assert np.all(frame_angle(got_R, R) < 2e-4), frame_angle(got_R, R)
    assert res.twist_coefficients.shape == (3, basis.shape[1]) and np.abs(res.twist_coefficients).max() > 0.05
    plain = reach(spec, tip, basis=basis, bound=2.0, tol=1e-6)
    assert plain.converged.all() and np.isnan(plain.orientation_error).all()
    _, plain_R = _pose_of(spec, plain.kappa_bar, plain.tau_bar)
    assert frame_angle(plain_R, R).max() > 0.1


def test_bad_tip_frames_are_refused():
    spec = load_scene(asset_path("scenes/arm.toml"))
    eye = np.eye(3)[None]
    with pytest.raises(ReachError, match="rotation matrix"):
        reach(spec, [[0.1, 0.0, 0.9]], orientations=2.0 * eye)
    with pytest.raises(ReachError, match=r"\(B = 1, 3, 3\)"):
        reach(spec, [[0.1, 0.0, 0.9]], orientations=np.eye(3))
    with pytest.raises(ReachError, match="3-D scene"):
        reach(load_scene(asset_path("scenes/arm_2d.toml")), [[0.1, 0.0, 0.9]], orientations=eye)
