"""`rodlab fit --starts K` (sim.analysis.multistart): the starts are the envs of one batched rollout, each with the
residuals and Jacobian it has alone; the search finds the minimum a single start misses; what the envs of a batch
cannot differ in is refused by name."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sim.analysis import calibration as F
from sim.analysis import start_points
from sim.analysis.multistart import LOG_SPREAD
from sim.scene.model import build_model
from sim.scene.spec import dump_scene, load_scene
from tests.helpers.cli import rodlab
from tests.helpers.fit import NOISE_M, commanded_scene, rod_on_a_sphere, synthetic, write_csv
from tests.helpers.rodspec import make_spec


def _each_env_as_alone(prob, Z):
    """The batched rollout's residuals and Jacobian of every env at Z equal its own one-env problem's."""
    tape = prob.rollouts(Z)
    J = prob.jacobians(tape, Z)
    for e, z in enumerate(Z):
        alone = prob.rollout(z)
        np.testing.assert_allclose(prob.residuals(tape, e), prob.residuals(alone), rtol=0, atol=1e-12)
        want = prob.jacobian(alone, z)
        assert np.abs(J[e] - want).max() <= 1e-9 * np.abs(want).max(), e


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_each_start_of_a_batch_has_the_residuals_and_jacobian_it_has_alone(tmp_path, mode):
    """Material factors, damping, gravity, the base and the actuation map differ per env: the batched rollout's
    residuals and tangent-mode Jacobian of each env equal its own one-env fit problem's."""
    spec, cmds = commanded_scene(tmp_path, mode)
    params = ["youngs_modulus", "density", "radius", "damping", "gravity", "base_position", "base_orientation",
              "actuation_gain", "actuation_lag"]
    meas, _ = synthetic(spec, ["damping"], [0.2], cmds=cmds, seconds=0.4)
    prob = F.Problem(spec, meas, cmds, params)
    Z = start_points(prob, 3, np.random.default_rng(1))
    assert np.all(np.abs(np.diff(Z, axis=0)).max(axis=0) > 0.0)  # every unknown differs between starts
    _each_env_as_alone(prob, Z)


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_each_start_may_place_the_obstacles_elsewhere(mode):
    """obstacle_position (and the stiffness) per env: a rod resting on a sphere placed differently in each start; the
    batched residuals and Jacobian of each env equal its own problem's (the obstacles' poses are per env)."""
    spec = rod_on_a_sphere((0.45, 0.0, -0.12), mode)
    meas, _ = synthetic(spec, ["damping"], [2.0], seconds=0.3)
    prob = F.Problem(spec, meas, None, ["obstacle_position", "youngs_modulus"])
    Z = start_points(prob, 3, np.random.default_rng(1))
    _each_env_as_alone(prob, Z)


def test_start_points_begin_at_the_scene_and_stay_in_bounds(tmp_path):
    spec, cmds = commanded_scene(tmp_path, "3d")
    meas, _ = synthetic(spec, ["damping"], [0.2], cmds=cmds, seconds=0.2)
    prob = F.Problem(spec, meas, cmds, ["youngs_modulus", "damping", "actuation_lag"])
    Z = start_points(prob, 64, np.random.default_rng(0))
    lo, hi = prob.bounds()
    assert np.array_equal(Z[0], prob.z0()) and np.all(Z >= lo) and np.all(Z <= hi)
    assert np.abs(Z[:, 0]).max() <= LOG_SPREAD and np.abs(Z[:, 0]).max() > 0.8 * LOG_SPREAD
    assert len({tuple(z) for z in Z}) == 64


def _swinging(tmp_path):
    """A stiff, lightly damped rod without gravity, its curvature stepped at one node at t = 0: it swings about the bent
    shape the command sets whatever its stiffness, several periods in the measured time, so the squared residual in
    the stiffness has a minimum per count of periods: (scene, commands)."""
    spec = make_spec(nodes=9, length=1.0, radius=0.01, E=2e8, dt=0.005, damping=0.05, max_iter=30, mode="2d")
    path = tmp_path / "step.csv"
    path.write_text("t,node,kappa1,kappa2,twist\n0,4,0.4,0,0\n")
    return spec, F.load_controls(path, build_model(spec))


def test_several_starts_find_the_minimum_one_start_misses(tmp_path):
    spec, cmds = _swinging(tmp_path)
    truth = math.log(3.5)  # the data's stiffness: 3.5 times the scene's
    meas, _ = synthetic(spec, ["youngs_modulus"], [truth], cmds=cmds, seconds=0.75)  # several periods
    one = F.fit(spec, meas, ["youngs_modulus"], cmds=cmds)
    assert one.rms_m > 10 * NOISE_M, one.rms_m  # a wrong minimum: the premise of the test
    many = F.fit(spec, meas, ["youngs_modulus"], cmds=cmds, starts=8, seed=0)
    assert many.params["youngs_modulus"] == pytest.approx(3.5 * spec.rods[0].youngs_modulus, rel=0.01)
    assert many.rms_m == pytest.approx(NOISE_M, rel=0.15) and not many.interrupted
    rms = [s["rms_m"] for s in many.starts]
    assert len(rms) == 8 and rms == sorted(rms) and rms[-1] > 10 * NOISE_M  # other starts ended in other minima
    assert rms[0] == pytest.approx(many.rms_m, rel=0.05)  # the polish only refines the best
    assert many.starts[0]["from"]["youngs_modulus"] != spec.rods[0].youngs_modulus  # not the scene's own start


def test_what_the_starts_cannot_differ_in_is_refused_by_name(tmp_path):
    spec, cmds = commanded_scene(tmp_path, "3d")
    meas, _ = synthetic(spec, ["damping"], [0.2], cmds=cmds, seconds=0.2)
    with pytest.raises(F.FitError, match="--starts needs --method lm"):
        F.fit(spec, meas, ["damping"], starts=2, method="lbfgs")
    with pytest.raises(F.FitError, match="--starts must be an integer >= 1"):
        F.fit(spec, meas, ["damping"], starts=0)
    ball = rod_on_a_sphere((0.45, 0.0, -0.12), "3d")
    m2, _ = synthetic(ball, ["damping"], [2.0], seconds=0.2)
    with pytest.raises(F.FitError, match="--starts: friction is a \\[contact\\] setting"):
        F.fit(ball, m2, ["friction"], starts=2)
    with pytest.raises(F.FitError, match="--starts: .*edge_radius.*one start"):
        F.fit(ball, m2, ["radius"], starts=2)


def test_cli_starts_reports_every_start(tmp_path, capsys):
    spec, _ = commanded_scene(tmp_path, "3d")
    path = tmp_path / "scene.toml"
    dump_scene(spec, path)
    meas, _ = synthetic(spec, ["youngs_modulus"], [math.log(1.5)], seconds=0.5)
    data = write_csv(tmp_path / "data.csv", meas)
    out = rodlab(capsys, "fit", str(path), str(data), "--params", "youngs_modulus,damping", "--starts", "3", "--seed",
                 "2", "--json", "--out", str(tmp_path / "fitted.toml"))
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    assert len(doc["starts"]) == 3 and doc["starts"][0]["rms_m"] <= doc["starts"][-1]["rms_m"]
    assert doc["params"]["youngs_modulus"] == pytest.approx(1.5 * spec.rods[0].youngs_modulus, rel=0.02)
    assert load_scene(tmp_path / "fitted.toml").rods[0].youngs_modulus == doc["params"]["youngs_modulus"]
    bad = rodlab(capsys, "fit", str(path), str(data), "--params", "damping", "--starts", "2", "--method", "lbfgs",
                 "--out", str(tmp_path / "other.toml"))
    assert bad.returncode == 2 and "--starts needs --method lm" in bad.stderr and not (tmp_path / "other.toml").exists()
