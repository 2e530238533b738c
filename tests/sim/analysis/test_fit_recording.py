"""`rodlab fit` of a rodlab .rrd recording (sim-to-sim, policies.recording.fitdata): episodes of a scene recorded
with rodlab's Recorder at known parameters, read back as (t, s, pos), and fitted from a perturbed start."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from policies.recording import Recorder, StaticScene
from policies.recording.fitdata import read_rrd_measurements, recording_to_measurements
from sim.analysis import calibration as F
from sim.scene.model import build_model
from sim.scene.spec import dump_scene, load_scene
from sim.step import Simulator
from tests.helpers.cli import rodlab
from tests.helpers.rodspec import make_spec

DIRECTION = tuple(np.array([1.0, 0.0, 0.3]) / np.hypot(1.0, 0.3))
SECONDS = 1.0


def _scene(tmp_path: Path) -> Path:
    p = tmp_path / "rod.toml"
    dump_scene(make_spec(nodes=9, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=0.2, max_iter=30,
                         direction=DIRECTION), p)
    return p


def _record(path: Path, specs: list) -> None:
    """One episode per scene in ``specs``: the node positions at reset and after every step for SECONDS, each frame
    logged at its simulated time (the last one twice, at the next control step)."""
    with Recorder(path) as rec:
        for spec in specs:
            model = build_model(spec)
            sim = Simulator(model, 1)
            state, ctrl = sim.reset(), sim.make_control()
            rec.begin_episode({"task": "fit", "policy": "scripted"}, StaticScene(rod_radius=spec.rods[0].radius))
            steps = int(round(SECONDS / model.dt))
            for k in range(steps + 1):
                rec.log_step(control_step=k, sim_time=k * model.dt, node_pos=state.dof[0, :, :3])
                if k < steps:
                    sim.step(state, ctrl)
            rec.log_step(control_step=steps + 1, sim_time=steps * model.dt, node_pos=state.dof[0, :, :3])
            rec.end_episode()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """rod.toml (E = 1 MPa, damping 0.2 1/s) and run.rrd: episode 0 at E = 1.3 MPa, episode 1 at damping 0.5."""
    tmp = tmp_path_factory.mktemp("fit_rrd")
    path = _scene(tmp)
    spec = load_scene(path)
    stiff = dataclasses.replace(spec, rods=(dataclasses.replace(spec.rods[0], youngs_modulus=1.3e6),))
    damped = dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, damping=0.5))
    _record(tmp / "run.rrd", [stiff, damped])
    return path, tmp / "run.rrd"


def test_a_recording_reads_as_the_arrays_of_an_npz(recorded):
    path, rrd = recorded
    spec = load_scene(path)
    t, s, pos = recording_to_measurements(rrd, 0, spec=spec)
    steps = int(round(SECONDS / 0.02))
    assert t.shape == (steps + 1,) and pos.shape == (steps + 1, 9, 3)  # the frame logged twice counts once
    np.testing.assert_allclose(t, np.arange(steps + 1) * 0.02, atol=1e-9)
    np.testing.assert_allclose(s, np.linspace(0.0, 1.0, 9), atol=1e-12)  # along the rest shape: the nodes' s
    np.testing.assert_allclose(pos[0], build_model(spec).rest_node_pos, atol=1e-6)  # float32 as stored
    t_free, s_free, _ = recording_to_measurements(rrd, 1)  # without the scene: s along the first frame
    np.testing.assert_allclose(s_free, s, atol=1e-6)
    meas = read_rrd_measurements(rrd, spec, episode=1)
    assert meas.t.size == (steps + 1) * 9 and set(meas.rod.tolist()) == {0}
    with pytest.raises(F.FitError, match=r"run.rrd: no episode 5 \(the file has episode\(s\) 0, 1\)"):
        read_rrd_measurements(rrd, spec, episode=5)
    other = make_spec(nodes=7, dt=0.02, direction=DIRECTION)
    with pytest.raises(F.FitError, match="has 9 recorded nodes but the scene's rod 'rod' has 7"):
        read_rrd_measurements(rrd, other, episode=0)
    with pytest.raises(F.FitError, match="a .rrd recording is read by `rodlab fit`"):
        F.load_measurements(rrd, spec)  # sim alone does not read recordings


@pytest.mark.parametrize("episode, param, truth", [(0, "youngs_modulus", 1.3e6), (1, "damping", 0.5)])
def test_rodlab_fit_recovers_a_recorded_parameter(recorded, tmp_path, capsys, episode, param, truth):
    path, rrd = recorded
    p = rodlab(capsys, "fit", str(path), str(rrd), "--params", param, "--episode", str(episode), "--out",
               str(tmp_path / "fitted.toml"), "--report", str(tmp_path / "report"), "--json")
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout.strip().splitlines()[-1])
    start = {"youngs_modulus": 1e6, "damping": 0.2}[param]
    assert abs(start / truth - 1.0) > 0.2  # a perturbed start
    assert doc["params"][param] == pytest.approx(truth, rel=0.01)
    assert doc["rms_m"] < 1e-5  # the recording's float32 rounding, not a misfit
    report = json.loads((tmp_path / "report" / "fit.json").read_text())
    assert report["data"] == str(rrd) and len(report["plots"]) == 4
