"""`rodlab fit` (sim.analysis.calibration): parameters recovered from synthetic measurements made by rodlab at known values plus
1 mm noise, standard errors consistent with the errors over noise draws, the actuation map, parameters the data
cannot separate said, held-out error, Ctrl-C keeping the best so far, bounds from the validation table, the report
folder (plots, held-out residuals), and bad input refused by name."""
from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.analysis import calibration as F
from sim.scene.spec import dump_scene, load_scene
from sim.scene.validate import BOUNDS
from tests.helpers.cli import rodlab
from tests.helpers.fit import NOISE_M, rod_on_a_sphere, synthetic, write_csv
from tests.helpers.rodspec import make_spec


def scene(tmp_path: Path, mode: str = "3d") -> Path:
    """A 9-node clamped rod leaning over under gravity, damped, Newton converged tightly, as a scene file."""
    p = tmp_path / f"rod_{mode}.toml"
    direction = tuple(np.array([1.0, 0.0, 0.3]) / np.hypot(1.0, 0.3))
    dump_scene(make_spec(nodes=9, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=0.2, max_iter=30, mode=mode,
                         direction=direction), p)
    return p


def test_stiffness_and_damping_are_recovered_with_consistent_standard_errors(tmp_path):
    spec = load_scene(scene(tmp_path))
    params = ["youngs_modulus", "damping"]
    truth = {"youngs_modulus": 1.3e6, "damping": 0.5}
    z_true = [math.log(1.3), 0.5]
    zs = []
    for seed in range(4):  # noise draws
        meas, _ = synthetic(spec, params, z_true, seed=seed)
        res = F.fit(spec, meas, params)
        assert res.rms_m == pytest.approx(NOISE_M, rel=0.15)  # the fit leaves the noise
        for k, v in truth.items():
            assert res.params[k] == pytest.approx(v, rel=0.02), (k, res.params)
            zs.append((res.params[k] - v) / res.stderr[k])
        assert res.confounded == [] and not res.interrupted and res.unconverged_steps == 0
    zs = np.array(zs)
    # errors in units of the reported standard error: of order one (not 10 or 0.01) over the draws
    assert np.all(np.abs(zs) < 4.0), zs
    assert 0.2 < float(np.sqrt(np.mean(zs**2))) < 3.0, zs


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_radius_is_recovered_with_the_stiffness(tmp_path, mode):
    """Against the weight and inertia (∝ r²) the bending stiffness (∝ E r⁴) sets E r² and the stretching stiffness
    (∝ E r²) E alone: this soft rod (1 MPa) stretches by ~1 % under its weight, so its motion tells both. Fitted
    from 20 % and 30 % off; the fitted scene holds the radius; a rod without a radius is refused by name."""
    spec = load_scene(scene(tmp_path, mode))
    meas, _ = synthetic(spec, ["radius", "youngs_modulus"], [math.log(1.2), math.log(1.3)], seconds=1.0)
    res = F.fit(spec, meas, ["radius", "youngs_modulus"])
    r0 = spec.rods[0].radius
    assert res.params["radius"] == pytest.approx(1.2 * r0, rel=0.01), res.params
    assert res.params["youngs_modulus"] == pytest.approx(1.3e6, rel=0.02), res.params
    assert abs(res.params["radius"] - 1.2 * r0) < 4.0 * res.stderr["radius"]
    assert res.spec.rods[0].radius == res.params["radius"] and res.confounded == []
    strip = dataclasses.replace(spec, rods=(dataclasses.replace(spec.rods[0], cross_section="rectangle",
                                                                width=0.02, height=0.01),))
    with pytest.raises(F.FitError, match="radius: rod .* non-circular section"):
        F.fit(strip, meas, ["radius"])


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_rest_curvature_is_recovered_and_held_by_the_fitted_scene(tmp_path, mode):
    """rest_kappa: the natural curvature of every interior node, fitted from a straight guess to a rod whose natural
    curvature bends it (every component; 2-D: the in-plane one), each within 4 standard errors. The fitted scene
    holds it as natural_curvature: built again, its rest controls are the fitted ones."""
    from sim.scene.model import build_model
    from sim.step import Simulator
    spec = load_scene(scene(tmp_path, mode))
    probe = F.Problem(spec, synthetic(spec, ["damping"], [0.2], seconds=0.1)[0], None, ["rest_kappa"])
    z_true = np.random.default_rng(3).normal(0.0, 0.05, len(probe.unknowns))
    meas, _ = synthetic(spec, ["rest_kappa"], z_true, seconds=1.0)
    res = F.fit(spec, meas, ["rest_kappa"])
    got = np.array([res.params[u.label] for u in probe.unknowns])
    se = np.array([res.stderr[u.label] for u in probe.unknowns])
    assert np.all(np.abs(got - z_true) < 4.0 * se + 1e-9) and res.confounded == []
    # 5 markers for 7 nodes' curvature, 1 mm noise: within 0.3 of the truth's spread (the straight guess: 1.0)
    assert np.sqrt(np.mean((got - z_true) ** 2)) < 0.3 * np.sqrt(np.mean(z_true ** 2))
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.2) and res.unconverged_steps == 0
    kb_fit = probe.controls_at(got)[0][0]
    kb_scene = Simulator(build_model(res.spec), 1).make_control().kappa_bar[0]
    assert np.allclose(kb_scene, kb_fit, atol=1e-12), (kb_scene, kb_fit)
    assert res.spec.rods[0].natural_curvature is not None


def test_the_adjoint_gradient_is_the_jacobian_transposed_times_the_residuals(tmp_path):
    """Jᵀ r from one adjoint pass equals the tangent-mode Jacobian's, for log factors, a rate, gravity and the
    actuation map (its commands enter every step's natural curvature)."""
    spec = load_scene(scene(tmp_path))
    path = tmp_path / "controls.csv"
    path.write_text("t,node,kappa1,kappa2,twist\n0,3,0.2,-0.1,0.05\n0.5,3,-0.15,0,0\n0,6,0.3,0.1,0\n")
    from sim.scene.model import build_model
    cmds = F.load_controls(path, build_model(spec))
    params = ["youngs_modulus", "damping", "gravity", "actuation_gain", "actuation_offset", "actuation_lag"]
    meas, prob = synthetic(spec, ["youngs_modulus"], [0.1], cmds=cmds)
    prob = F.Problem(spec, meas, cmds, params)
    z = prob.z0() + np.random.default_rng(0).normal(0.0, 0.05, len(prob.unknowns))
    z[[u.name == "actuation_lag" for u in prob.unknowns]] = 0.05
    tape = prob.rollout(z)
    r = prob.residuals(tape)
    want = prob.jacobian(tape, z).T @ r
    got = prob.gradient(tape, z, r)
    assert np.abs(got - want).max() <= 1e-9 * np.abs(want).max(), (got, want)


def test_lbfgs_with_the_adjoint_recovers_the_parameters(tmp_path):
    spec = load_scene(scene(tmp_path))
    params = ["youngs_modulus", "damping"]
    meas, _ = synthetic(spec, params, [math.log(1.3), 0.5], seed=1)
    res = F.fit(spec, meas, params, method="lbfgs", max_iterations=200)
    assert res.params["youngs_modulus"] == pytest.approx(1.3e6, rel=0.02), res.params
    assert res.params["damping"] == pytest.approx(0.5, rel=0.02), res.params
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.15) and not res.interrupted
    lm = F.fit(spec, meas, params)  # the same minimum as least squares
    for k in params:
        assert res.params[k] == pytest.approx(lm.params[k], rel=1e-3), (res.params, lm.params)
    with pytest.raises(F.FitError, match="unknown method 'newton'"):
        F.fit(spec, meas, params, method="newton")


def test_the_actuation_map_is_recovered_from_commanded_curvature(tmp_path):
    """2-D arm driven by commanded curvature at two nodes; the rod bends gain · command + offset."""
    spec = load_scene(scene(tmp_path, "2d"))
    path = tmp_path / "controls.csv"
    path.write_text("t,node,kappa1,kappa2,twist\n0,3,0.2,0,0\n0.5,3,-0.15,0,0\n0,6,0.3,0,0\n0.8,6,-0.2,0,0\n")
    from sim.scene.model import build_model
    cmds = F.load_controls(path, build_model(spec))
    params = ["actuation_gain", "actuation_offset"]
    z_true = [0.8, 1.2, 0.02, -0.03]  # gains of nodes 3, 6; offsets of nodes 3, 6 (κ1)
    meas, prob = synthetic(spec, params, z_true, cmds=cmds)
    assert [u.label for u in prob.unknowns] == ["actuation_gain[3]", "actuation_gain[6]",
                                                "actuation_offset[3].kappa1", "actuation_offset[6].kappa1"]
    res = F.fit(spec, meas, params, cmds=cmds)
    got = list(res.params.values())
    np.testing.assert_allclose(got[:2], z_true[:2], rtol=0.02)
    np.testing.assert_allclose(got[2:], z_true[2:], atol=0.002)


def _controls(tmp_path, spec):
    path = tmp_path / "controls.csv"
    path.write_text("t,node,kappa1,kappa2,twist\n0,3,0.2,0,0\n0.5,3,-0.15,0,0\n0,6,0.3,0,0\n0.8,6,-0.2,0,0\n")
    from sim.scene.model import build_model
    return F.load_controls(path, build_model(spec))


def test_lag_schedule_is_the_backward_euler_first_order_lag_and_its_exact_derivative():
    dt, tau = 0.02, 0.15
    c = np.zeros((200, 2))
    c[10:] = [1.0, -0.5]  # a step command at t = 0.2 s
    f, df = F.lag_schedule(c, tau, dt)
    k = np.arange(10, 200)
    np.testing.assert_allclose(f[k, 0], 1.0 - (tau / (tau + dt)) ** (k - 9), rtol=1e-12)  # the closed form
    t = (k - 9) * dt  # against the continuous lag 1 − e^{−t/τ}: backward Euler, first order in dt
    assert np.max(np.abs(f[k, 0] - (1.0 - np.exp(-t / tau)))) < 0.6 * dt / tau
    np.testing.assert_allclose(f[:, 1], -0.5 * f[:, 0], rtol=1e-12)
    eps = 1e-6
    fd = (F.lag_schedule(c, tau + eps, dt)[0] - F.lag_schedule(c, tau - eps, dt)[0]) / (2 * eps)
    np.testing.assert_allclose(df, fd, rtol=1e-7, atol=1e-10)
    f0, df0 = F.lag_schedule(c, 0.0, dt)  # no lag: the commands themselves
    np.testing.assert_array_equal(f0, c)
    with pytest.raises(F.FitError, match="actuation_lag must be ≥ 0"):
        F.lag_schedule(c, -0.1, dt)


def test_play_schedule_is_a_backlash_and_its_derivative_is_exact_between_switches():
    c = 0.3 * np.sin(np.linspace(0.0, 4.0 * np.pi, 400))[:, None] * np.array([1.0, -2.0])
    w = 0.05
    y, dy = F.play_schedule(c, w)
    assert np.all(np.abs(y - c) <= w + 1e-15)  # never more than w behind the command
    moving = np.abs(np.diff(y[:, 0])) > 0
    dragged = np.isclose(np.abs(y[1:, 0] - c[1:, 0]), w)
    assert np.all(dragged[moving]) and not np.all(moving)  # it moves only when dragged, and holds at reversals
    up = np.diff(c[:, 0]) > 0  # hysteresis: below the command on the way up, above on the way down
    np.testing.assert_allclose(y[1:, 0][up & dragged], c[1:, 0][up & dragged] - w)
    np.testing.assert_allclose(y[1:, 0][~up & dragged], c[1:, 0][~up & dragged] + w)
    eps = 1e-7
    fd = (F.play_schedule(c, w + eps)[0] - F.play_schedule(c, w - eps)[0]) / (2 * eps)
    np.testing.assert_allclose(dy, fd, atol=1e-7)
    assert set(np.unique(dy)) <= {-1.0, 0.0, 1.0}
    np.testing.assert_array_equal(F.play_schedule(c, 0.0)[0], c)  # no play: the commands themselves
    with pytest.raises(F.FitError, match="actuation_play must be ≥ 0"):
        F.play_schedule(c, -0.1)


def _swept_controls(tmp_path, spec):
    """Nodes 3 and 6 swept back and forth (steps of a slow sine of changing amplitude): the play shows."""
    path = tmp_path / "swept.csv"
    rows = ["t,node,kappa1,kappa2,twist"]
    for node, amp, f in ((3, 0.25, 1.1), (6, 0.3, 0.8)):
        for t in np.arange(0.0, 2.0, 0.05):
            k = amp * (0.6 + 0.4 * np.cos(1.3 * t)) * np.sin(2 * np.pi * f * t)
            rows.append(f"{t:.3f},{node},{k:.6f},{0.5 * k:.6f},0")
    path.write_text("\n".join(rows) + "\n")
    from sim.scene.model import build_model
    return F.load_controls(path, build_model(spec))


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_play_and_lag_columns_of_the_fit_jacobian_match_finite_differences(tmp_path, mode):
    spec = load_scene(scene(tmp_path, mode))
    cmds = _swept_controls(tmp_path, spec)
    params = ["actuation_gain", "actuation_play", "actuation_lag"]
    meas, prob = synthetic(spec, params, [0.8, 1.2, 0.04, 0.1], cmds=cmds, seconds=1.0)
    z = np.array([0.9, 1.1, 0.03, 0.07])
    J = prob.jacobian(prob.rollout(z), z)
    for q, h in ((1, 1e-6), (2, 1e-7), (3, 1e-6)):  # gain of node 6, play, lag
        dz = np.zeros(4)
        dz[q] = h
        fd = (prob.residuals(prob.rollout(z + dz)) - prob.residuals(prob.rollout(z - dz))) / (2 * h)
        scale = np.max(np.abs(fd))
        assert scale > 1e-3, q  # the points move
        assert np.max(np.abs(J[:, q] - fd)) < 1e-5 * scale, (q, np.max(np.abs(J[:, q] - fd)) / scale)


def test_the_actuators_lag_is_recovered_with_the_gains(tmp_path):
    """The 2-D arm's actuators follow the commands with a 0.12 s lag: fitted with the gains from no lag."""
    spec = load_scene(scene(tmp_path, "2d"))
    cmds = _controls(tmp_path, spec)
    params = ["actuation_gain", "actuation_lag"]
    z_true = [0.8, 1.2, 0.12]
    meas, prob = synthetic(spec, params, z_true, cmds=cmds)
    assert [u.label for u in prob.unknowns] == ["actuation_gain[3]", "actuation_gain[6]", "actuation_lag"]
    res = F.fit(spec, meas, params, cmds=cmds)
    assert res.params["actuation_lag"] == pytest.approx(0.12, rel=0.05), res.params
    np.testing.assert_allclose([res.params["actuation_gain[3]"], res.params["actuation_gain[6]"]], z_true[:2],
                               rtol=0.02)
    assert abs(res.params["actuation_lag"] - 0.12) < 4 * res.stderr["actuation_lag"] + 1e-9
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.15) and res.at_bound == []
    no_lag = F.fit(spec, meas, ["actuation_gain"], cmds=cmds)  # the lag the data show cannot be left out
    assert no_lag.rms_m > 2 * res.rms_m


def test_the_actuators_play_is_recovered_with_their_lag_and_gains(tmp_path):
    """The 2-D arm's actuators have a backlash of ±0.04 and a 0.1 s lag: fitted from no play and no lag."""
    spec = load_scene(scene(tmp_path, "2d"))
    cmds = _swept_controls(tmp_path, spec)
    params = ["actuation_gain", "actuation_play", "actuation_lag"]
    z_true = [0.8, 1.2, 0.04, 0.1]
    meas, prob = synthetic(spec, params, z_true, cmds=cmds, seconds=2.0)
    assert prob.bounds()[1][2] == np.max(np.abs(prob.cmd_kb[..., 0]))  # the play at most the largest command
    res = F.fit(spec, meas, params, cmds=cmds)
    got = [res.params[u.label] for u in prob.unknowns]
    np.testing.assert_allclose(got, z_true, rtol=0.05)
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.15) and res.at_bound == [] and res.confounded == []
    assert res.stderr["actuation_play"] < 0.005 and abs(got[2] - 0.04) < 3 * res.stderr["actuation_play"]
    # the hysteresis left out: the lag takes it up (0.157 s) and the residual grows (1.06 against 0.97 mm)
    without = F.fit(spec, meas, ["actuation_gain", "actuation_lag"], cmds=cmds)
    assert without.rms_m > 1.05 * res.rms_m and without.params["actuation_lag"] > 0.13


def _sliding_rod(mu: float, mode: str = "3d"):
    """A free rod laid along a 30° incline (a plane obstacle) with friction μ: it slides down, slowed by friction."""
    from sim.scene.obstacles import ContactSpec, PlaneSpec
    a = math.radians(30.0)
    normal = (-math.sin(a), 0.0, math.cos(a))
    spec = make_spec(nodes=9, length=1.0, radius=0.01, dt=0.01, gravity=(0.0, 0.0, -9.8), max_iter=60, tol=1e-10,
                     dtol=1e-10, direction=(math.cos(a), 0.0, math.sin(a)), start=tuple(0.0105 * np.array(normal)),
                     clamp="none", mode=mode)
    return dataclasses.replace(spec, obstacles=(PlaneSpec(point=(0.0, 0.0, 0.0), normal=normal),),
                               contact=ContactSpec(stiffness=1e4, delta=1e-3, friction=mu))


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_friction_coefficient_is_recovered_from_a_rod_sliding_down_an_incline(mode):
    """The slide's deceleration sets μ (g (sin α − μ cos α) along the slope): fitted from half the true value, with
    the exact derivatives through the frictional contact."""
    truth = _sliding_rod(0.4, mode)
    meas, _ = synthetic(truth, ["friction"], [0.4], seconds=0.8)
    res = F.fit(_sliding_rod(0.2, mode), meas, ["friction"])
    assert res.params["friction"] == pytest.approx(0.4, abs=0.01), res.params
    assert abs(res.params["friction"] - 0.4) < 4 * res.stderr["friction"] + 1e-9
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.15) and res.unconverged_steps == 0
    assert res.spec.contact.friction == res.params["friction"]


def test_the_contact_distance_is_recovered_from_the_rod_resting_on_a_sphere():
    """The contact's δ sets how far above the sphere the rod comes to rest: fitted from half the true value."""
    center = (0.45, 0.0, -0.12)
    meas, _ = synthetic(rod_on_a_sphere(center, "2d", delta=2e-2), ["damping"], [2.0], seconds=0.8)
    res = F.fit(rod_on_a_sphere(center, "2d", delta=1e-2), meas, ["contact_delta"])
    assert res.params["contact_delta"] == pytest.approx(2e-2, rel=0.05), res.params
    assert abs(res.params["contact_delta"] - 2e-2) < 4.0 * res.stderr["contact_delta"]
    assert res.spec.contact.delta == res.params["contact_delta"] and res.unconverged_steps == 0


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_an_obstacle_position_is_recovered_from_the_rod_resting_on_it(mode):
    """Where the rod comes to rest on the sphere sets where the sphere is: its position recovered from a guess 1 cm
    off, within its standard errors (the height to 1 mm), with the exact derivatives with respect to the obstacle's
    pose; the fitted scene holds it."""
    truth = (0.46, 0.004 if mode == "3d" else 0.0, -0.118)
    guess = (0.45, 0.0, -0.12)
    axes = (0, 1, 2) if mode == "3d" else (0, 2)
    meas, _ = synthetic(rod_on_a_sphere(truth, mode), ["damping"], [2.0], seconds=0.8)
    res = F.fit(rod_on_a_sphere(guess, mode), meas, ["obstacle_position"])
    got = [res.params[f"obstacle_position[ball].{'xyz'[a]}"] for a in axes]
    for a, v in zip(axes, got):  # within the reported uncertainty (the rest shape barely tells x: a tip on a ball)
        se = res.stderr[f"obstacle_position[ball].{'xyz'[a]}"]
        assert abs(v - truth[a]) < 4.0 * se, (a, v, se)
    assert got[-1] == pytest.approx(truth[2], abs=1e-3)  # the height the rod rests at: well determined
    assert res.spec.obstacles[0].center == pytest.approx(tuple(got[axes.index(a)] if a in axes else guess[a]
                                                               for a in range(3)))
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.2) and res.unconverged_steps == 0


def _rod_across_a_rod(delta):
    """3-D: a cantilever (the measured rod, first) sagging onto a stiff rod clamped across under its middle."""
    from sim.scene.obstacles import ContactSpec
    spec = make_spec(nodes=9, length=0.5, radius=0.01, E=1e7, dt=0.01, gravity=(0.0, 0.0, -9.8), damping=2.0,
                     max_iter=60, tol=1e-10, dtol=1e-10, line_search="auto")
    top = spec.rods[0]
    under = dataclasses.replace(top, name="under", start=(0.3, -0.25, -0.05), direction=(0.0, 1.0, 0.0),
                                youngs_modulus=1e10)
    return dataclasses.replace(spec, rods=(top, under), contact=ContactSpec(stiffness=1e4, delta=delta,
                                                                            rod_contact=True))


def test_the_contact_distance_between_two_rods_is_recovered_from_one_resting_on_the_other():
    """Contact between edges: δ sets how far above the rod under it the cantilever comes to rest; fitted from half
    the true value with the derivatives through the edge pairs."""
    meas, _ = synthetic(_rod_across_a_rod(2e-2), ["damping"], [2.0], seconds=0.8)
    res = F.fit(_rod_across_a_rod(1e-2), meas, ["contact_delta"])
    assert res.params["contact_delta"] == pytest.approx(2e-2, rel=0.05), res.params
    assert abs(res.params["contact_delta"] - 2e-2) < 4.0 * res.stderr["contact_delta"]
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.2) and res.unconverged_steps == 0


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_base_position_is_recovered_against_an_obstacle(mode):
    """base_position: the rod and its clamp moved; it sags onto a sphere fixed in the world, so the shift changes how
    it rests, not only where. Recovered to a fraction of a millimetre from a guess a few centimetres off, each axis
    within 4 standard errors; the fitted scene's rod starts there."""
    center = (0.45, 0.0, -0.12)
    truth = rod_on_a_sphere(center, mode)
    shift = np.array([0.02, -0.01 if mode == "3d" else 0.0, 0.015])
    moved = dataclasses.replace(truth, rods=(dataclasses.replace(
        truth.rods[0], start=tuple(np.array(truth.rods[0].start) + shift)),))
    meas, _ = synthetic(moved, ["damping"], [2.0], seconds=0.8)
    res = F.fit(truth, meas, ["base_position"])
    axes = (0, 2) if mode == "2d" else (0, 1, 2)
    for a in axes:
        label = f"base_position.{'xyz'[a]}"
        got = res.params[label] - truth.rods[0].start[a]
        assert abs(got - shift[a]) < 5e-4 and abs(got - shift[a]) < 4.0 * res.stderr[label] + 1e-9, (a, got)
    assert res.spec.rods[0].start == pytest.approx(tuple(np.array(truth.rods[0].start) + shift), abs=5e-4)
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.2) and res.unconverged_steps == 0


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_base_orientation_column_matches_central_differences(tmp_path, mode):
    """base_orientation's tangent (the initial positions turned about the base, and in 3-D the twist angles that make
    the carried frames the turned scene's own) against central differences of the fit's residuals over whole
    rollouts, with curvature commanded at two nodes (the material frame matters), at a turned and shifted base."""
    from tests.helpers.fit import commanded_scene
    spec, cmds = commanded_scene(tmp_path, mode)
    meas, _ = synthetic(spec, ["damping"], [0.2], cmds=cmds, seconds=0.4)
    prob = F.Problem(spec, meas, cmds, ["base_orientation", "base_position"])
    z = prob.z0() + np.array([0.05, -0.03, 0.01, 0.0, 0.02][:len(prob.unknowns)])
    J = prob.jacobian(prob.rollout(z), z)
    for q, u in enumerate(prob.unknowns):
        errs = []
        for h in (1e-4, 1e-5, 1e-6):  # the step-size study: the difference's truncation, then its rounding
            zp, zm = z.copy(), z.copy()
            zp[q] += h
            zm[q] -= h
            fd = (prob.residuals(prob.rollout(zp)) - prob.residuals(prob.rollout(zm))) / (2.0 * h)
            errs.append(np.abs(fd - J[:, q]).max() / np.abs(fd).max())
        assert min(errs) < 2e-9, (u.label, errs)


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_the_base_orientation_is_recovered_and_held_by_the_fitted_scene(tmp_path, mode):
    """A cantilever whose base is tilted leans differently under gravity: the tilt is recovered from an untilted
    guess within 4 standard errors (to a few mrad), and the fitted scene's rod starts in the fitted direction (its
    initial state is the one the fit simulated)."""
    from sim.scene.model import build_model
    from sim.step import Simulator
    spec = load_scene(scene(tmp_path, mode))
    truth = [0.12] if mode == "2d" else [0.1, -0.08]
    meas, prob = synthetic(spec, ["base_orientation"], truth, seconds=1.0)
    res = F.fit(spec, meas, ["base_orientation"])
    for u, want in zip(prob.unknowns, truth):
        got, se = res.params[u.label], res.stderr[u.label]
        assert abs(got - want) < 4.0 * se + 1e-9 and abs(got - want) < 5e-3, (u.label, got, se)
    assert res.rms_m == pytest.approx(NOISE_M, rel=0.2) and res.confounded == []
    z = np.array([res.params[u.label] for u in prob.unknowns])
    fitted = Simulator(build_model(res.spec), 1).reset()
    simulated = Simulator(build_model(prob.spec_at(z)), 1).reset()
    np.testing.assert_allclose(fitted.dof, simulated.dof, atol=1e-12)
    assert not np.allclose(fitted.dof, Simulator(build_model(spec), 1).reset().dof, atol=1e-3)


def test_contact_parameters_need_contact(tmp_path):
    spec = load_scene(scene(tmp_path))
    meas, _ = synthetic(spec, ["damping"], [0.5], seconds=0.2)
    for name in ("friction", "contact_stiffness", "contact_delta"):
        with pytest.raises(F.FitError, match=f"{name}: the scene has no contact"):
            F.fit(spec, meas, [name])
    with pytest.raises(F.FitError, match="obstacle_position: the scene has no obstacle contact"):
        F.fit(spec, meas, ["obstacle_position"])


def test_parameters_the_data_cannot_separate_are_said(tmp_path):
    """Gravity, inertia and damping all scale with the mass: motion sets only E/ρ."""
    spec = load_scene(scene(tmp_path))
    meas, _ = synthetic(spec, ["youngs_modulus"], [math.log(1.3)], seconds=0.6)
    res = F.fit(spec, meas, ["youngs_modulus", "density"])
    assert res.confounded == [["youngs_modulus", "density"]]
    assert math.isinf(res.stderr["youngs_modulus"]) and math.isinf(res.stderr["density"])
    assert res.params["youngs_modulus"] / res.params["density"] == pytest.approx(1.3e6 / 1000.0, rel=0.01)


def test_ctrl_c_keeps_the_best_so_far(tmp_path):
    spec = load_scene(scene(tmp_path))
    meas, _ = synthetic(spec, ["damping"], [0.5], seconds=0.5)
    seen = []

    def log(line):
        seen.append(line)
        if len(seen) == 3:
            raise KeyboardInterrupt

    res = F.fit(spec, meas, ["damping"], log=log)
    assert res.interrupted and len(seen) == 3
    start = F.fit(spec, meas, ["damping"], max_iterations=1)  # the starting point only
    assert res.rms_m <= start.rms_m


def test_cli_writes_a_new_scene_a_report_and_json(tmp_path, capsys):
    path = scene(tmp_path)
    spec = load_scene(path)
    meas, _ = synthetic(spec, ["youngs_modulus"], [math.log(1.3)], seconds=1.0)
    data = write_csv(tmp_path / "data.csv", meas)
    out = tmp_path / "fitted.toml"
    cmd = ["fit", str(path), str(data), "--params", "youngs_modulus", "--out", str(out), "--report",
           str(tmp_path / "report"), "--holdout", "0.25", "--json"]
    p = rodlab(capsys, *cmd)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout.strip().splitlines()[-1])
    assert doc["params"]["youngs_modulus"] == pytest.approx(1.3e6, rel=0.02)
    assert doc["holdout_rms_m"] < 3 * NOISE_M and doc["rms_m"] < 1.5 * NOISE_M
    assert load_scene(out).rods[0].youngs_modulus == pytest.approx(doc["params"]["youngs_modulus"])
    report = json.loads((tmp_path / "report" / "fit.json").read_text())
    assert report["fitted_scene"] == str(out) and report["correlation"]["labels"] == ["youngs_modulus"]
    assert report["plots"] == list(F.PLOTS) and all((tmp_path / "report" / n).is_file() for n in F.PLOTS)
    lines = (tmp_path / "report" / "residuals.csv").read_text().splitlines()
    assert lines[0] == "t,s,rod,dx,dy,dz,distance,split" and len(lines) == meas.t.size + 1
    assert {ln.rsplit(",", 1)[1] for ln in lines[1:]} == {"fit", "holdout"}
    # never over an existing file (the input scene included)
    for target in (out, path):
        p = rodlab(capsys, *cmd[:3], "--params", "damping", "--out", str(target))
        assert p.returncode == 2 and "always written to a new file" in p.stderr and "Traceback" not in p.stderr
    # the adjoint's L-BFGS reaches the same fit
    p = rodlab(capsys, *cmd[:5], "--out", str(tmp_path / "lbfgs.toml"), "--method", "lbfgs", "--json")
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout.strip().splitlines()[-1])["params"]["youngs_modulus"] == pytest.approx(
        doc["params"]["youngs_modulus"], rel=0.01)


def test_report_has_plots_and_the_held_out_residuals(tmp_path):
    """--report: fit.json lists the four plots, written atomically (no temporary file left); residuals.csv has every
    measured point with its split, the held-out rows' RMS being the held-out RMS; the track covers the whole motion."""
    import matplotlib.image

    spec = load_scene(scene(tmp_path))
    meas, _ = synthetic(spec, ["youngs_modulus", "damping"], [math.log(1.3), 0.5], seconds=1.0)
    res = F.fit(spec, meas, ["youngs_modulus", "damping"], holdout=0.25)
    cut = float(np.quantile(meas.t, 0.75))
    tr = res.track
    assert tr.measured_t.size == meas.t.size and np.array_equal(tr.held_out, meas.t >= cut)
    assert tr.t[-1] >= meas.t.max() - 1e-12 and tr.node_s.shape == (9,) and tr.axes == (0, 1, 2)
    folder = tmp_path / "report"
    written = F.write_report(folder, res, scene="rod.toml")
    assert [p.name for p in written] == [*F.PLOTS, "residuals.csv", "fit.json"]
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in written)  # no temporary file left
    doc = json.loads((folder / "fit.json").read_text())
    assert doc["plots"] == list(F.PLOTS) and doc["scene"] == "rod.toml"
    assert doc["holdout_rms_m"] == pytest.approx(res.holdout_rms_m)
    assert doc["correlation"]["labels"] == ["youngs_modulus", "damping"]
    for name in F.PLOTS:
        assert (folder / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        img = matplotlib.image.imread(folder / name)
        assert img.shape[0] >= 250 and img.shape[1] >= 250 and float(img[..., :3].std()) > 0.05, name
    lines = (folder / "residuals.csv").read_text().splitlines()
    assert lines[0] == ",".join(F.RESIDUAL_COLUMNS)
    rows = [ln.split(",") for ln in lines[1:]]
    assert len(rows) == meas.t.size
    t = np.array([float(r[0]) for r in rows])
    d = np.array([[float(v) for v in r[3:6]] for r in rows])
    split = np.array([r[7] for r in rows])
    assert set(split) == {"fit", "holdout"} and np.array_equal(split == "holdout", t >= cut)
    assert float(np.sqrt(np.mean(d[split == "holdout"] ** 2))) == pytest.approx(res.holdout_rms_m, rel=1e-6)
    assert float(np.sqrt(np.mean(d[split == "fit"] ** 2))) == pytest.approx(res.rms_m, rel=1e-6)
    # the plots are drawn on demand: importing sim.analysis.calibration loads no matplotlib
    code = "import sys, sim.analysis.calibration; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.strip() == "False", out.stderr


def test_report_of_a_2d_fit_draws_the_plane(tmp_path):
    spec = load_scene(scene(tmp_path, "2d"))
    meas, _ = synthetic(spec, ["damping"], [0.5], seconds=0.5)
    res = F.fit(spec, meas, ["damping"])
    assert res.track.axes == (0, 2) and not res.track.held_out.any()
    written = F.write_report(tmp_path / "r2", res)
    assert [p.name for p in written][:4] == list(F.PLOTS)
    assert {ln.rsplit(",", 1)[1] for ln in (tmp_path / "r2" / "residuals.csv").read_text().splitlines()[1:]} == \
        {"fit"}


def test_bounds_come_from_the_validation_table(tmp_path):
    """A fit whose optimum lies outside the valid scene values stops on the bound, says so, and its scene loads.
    Motion sets only E/ρ: data of a rod 4× as dense asks for E / 4 = 0.5 Pa, below the lowest valid 1 Pa."""
    direction = tuple(np.array([1.0, 0.0, 0.3]) / np.hypot(1.0, 0.3))
    spec = make_spec(nodes=9, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=0.2, max_iter=30, direction=direction,
                     E=2.0, density=0.002)
    meas, _ = synthetic(spec, ["density"], [math.log(4.0)], seconds=1.0)
    prob = F.Problem(spec, meas, None, ["youngs_modulus", "density", "shear_modulus", "damping", "gravity"])
    lo, hi = prob.bounds()
    E_lo, E_hi, _ = BOUNDS["rod.youngs_modulus"]
    R_lo, R_hi, _ = BOUNDS["rod.density"]
    np.testing.assert_allclose(lo, [math.log(E_lo / 2.0), math.log(R_lo / 0.002), 0.0, 0.0, -1e4, -1e4, -1e4])
    np.testing.assert_allclose(hi[[0, 1, 3, 4]], [math.log(E_hi / 2.0), math.log(R_hi / 0.002), 1e9, 1e4])
    assert hi[2] == pytest.approx(math.log(1.5 / 1e-9))  # ν = 0.5 may only go down (toward -1)
    res = F.fit(spec, meas, ["youngs_modulus"])
    assert res.params["youngs_modulus"] == pytest.approx(E_lo, rel=1e-9) and res.params["youngs_modulus"] >= E_lo
    assert res.at_bound == ["youngs_modulus"] and res.summary()["at_bound"] == ["youngs_modulus"]
    dump_scene(res.spec, tmp_path / "fitted.toml")
    assert load_scene(tmp_path / "fitted.toml").rods[0].youngs_modulus == res.params["youngs_modulus"]
    free = F.fit(spec, meas, ["damping"], max_iterations=3)  # inside its bounds: not said
    assert free.at_bound == []


@pytest.mark.parametrize("rows, message", [
    ("t,s,x,y,z\n0,0.5,0,0,0\n0.1,1.7,0,0,0\n", "data.csv:3: s = 1.7 m is off the rod"),
    ("t,s,x,y,z\n0,0.5,0,0,nan\n", "data.csv:2: z = 'nan' is not finite"),
    ("t,s,x,y,z\n0,0.5,0,0,abc\n", "data.csv:2: z = 'abc' is not a number"),
    ("t,s,x,y,z\n-1,0.5,0,0,0\n", "data.csv:2: t = -1 s is before"),
    ("t,s,x,y,z\n0,0.5,0,0,800\n", "data.csv:2: position [0.0, 0.0, 800.0] is more than 100 rod lengths"),
    ("t,s,x,z\n0,0.5,0,0\n", "data.csv: missing column(s) y"),
])
def test_bad_data_is_refused_by_row(tmp_path, rows, message):
    spec = load_scene(scene(tmp_path))
    (tmp_path / "data.csv").write_text(rows)
    with pytest.raises(F.FitError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        F.load_measurements(tmp_path / "data.csv", spec)


def test_bad_npz_and_parameter_names_are_refused(tmp_path):
    spec = load_scene(scene(tmp_path))
    np.savez(tmp_path / "d.npz", t=np.array([0.0, 0.2, 0.1]), s=np.array([0.5]), pos=np.zeros((3, 1, 3)))
    with pytest.raises(F.FitError, match=r"t is not increasing at t\[2\]"):
        F.load_measurements(tmp_path / "d.npz", spec)
    pos = np.full((2, 2, 3), np.nan)
    pos[1, 0] = [0.5, 0.0, 0.1]
    np.savez(tmp_path / "ok.npz", t=np.array([0.0, 0.1]), s=np.array([0.5, 1.0]), pos=pos)
    meas = F.load_measurements(tmp_path / "ok.npz", spec)
    assert meas.t.tolist() == [0.1]  # NaN points are missing, not data
    with pytest.raises(F.FitError, match="unknown parameter\\(s\\) 'stiffness'"):
        F.fit(spec, meas, ["stiffness"])
    with pytest.raises(F.FitError, match="needs --controls"):
        F.fit(spec, meas, ["actuation_gain"])
