"""`rodlab fit` (sim.fit): parameters recovered from synthetic measurements made by rodlab at known values plus
1 mm noise, standard errors consistent with the errors over noise draws, the actuation map, parameters the data
cannot separate said, held-out error, Ctrl-C keeping the best so far, and bad input refused by name."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sim import fit as F
from sim.scene import dump_scene, load_scene
from tests.helpers.fit import NOISE_M, synthetic, write_csv
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


def test_the_actuation_map_is_recovered_from_commanded_curvature(tmp_path):
    """2-D arm driven by commanded curvature at two nodes; the rod bends gain · command + offset."""
    spec = load_scene(scene(tmp_path, "2d"))
    path = tmp_path / "controls.csv"
    path.write_text("t,node,kappa1,kappa2,twist\n0,3,0.2,0,0\n0.5,3,-0.15,0,0\n0,6,0.3,0,0\n0.8,6,-0.2,0,0\n")
    from sim.model import build_model
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


def test_cli_writes_a_new_scene_a_report_and_json(tmp_path):
    path = scene(tmp_path)
    spec = load_scene(path)
    meas, _ = synthetic(spec, ["youngs_modulus"], [math.log(1.3)], seconds=1.0)
    data = write_csv(tmp_path / "data.csv", meas)
    out = tmp_path / "fitted.toml"
    cmd = [sys.executable, "-m", "rodlab_cli", "fit", str(path), str(data), "--params", "youngs_modulus",
           "--out", str(out), "--report", str(tmp_path / "report"), "--holdout", "0.25", "--json"]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout.strip().splitlines()[-1])
    assert doc["params"]["youngs_modulus"] == pytest.approx(1.3e6, rel=0.02)
    assert doc["holdout_rms_m"] < 3 * NOISE_M and doc["rms_m"] < 1.5 * NOISE_M
    assert load_scene(out).rods[0].youngs_modulus == pytest.approx(doc["params"]["youngs_modulus"])
    report = json.loads((tmp_path / "report" / "fit.json").read_text())
    assert report["fitted_scene"] == str(out) and report["correlation"]["labels"] == ["youngs_modulus"]
    lines = (tmp_path / "report" / "residuals.csv").read_text().splitlines()
    assert lines[0] == "t,s,rod,dx,dy,dz,distance" and len(lines) > 10
    # never over an existing file (the input scene included)
    for target in (out, path):
        p = subprocess.run(cmd[:6] + ["--params", "damping", "--out", str(target)], capture_output=True, text=True,
                           timeout=600)
        assert p.returncode == 2 and "always written to a new file" in p.stderr and "Traceback" not in p.stderr


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
