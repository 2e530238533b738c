"""The Fit tab (workbench.session.fitting, workbench.panels.fit) on a real workbench server: a fit of the live scene to synthetic
measurements made by rodlab at known parameters (1 mm noise) recovers them, shows its progress and result, draws
the fitted rod with the measured points and residuals, stops on request keeping the best so far, applies as a new
scene of the scenes folder (never over a file); data files are read only inside the data folder; bad data is
refused by row."""
from __future__ import annotations

import math
import os
import re

import numpy as np
import pytest

from sim.analysis import calibration as F
from sim.scene.spec import dump_scene, load_scene
from tests.helpers.fit import synthetic, write_csv
from tests.helpers.rodspec import make_spec
from tools.browser import wait_for
from workbench.session.files import FileAccessError, Folders
from workbench.session.fitting import FitJob, overlay_at

PARAMS = ["youngs_modulus", "damping"]
TRUTH = {"youngs_modulus": 1.3e6, "damping": 0.5}


def scene(tmp_path):
    """A 21-node clamped rod leaning over under gravity, damped, Newton converged tightly (the rod of
    tests/sim/analysis/test_fit.py with the workbench's 21 nodes), as a scene file."""
    p = tmp_path / "rod_3d.toml"
    direction = tuple(np.array([1.0, 0.0, 0.3]) / np.hypot(1.0, 0.3))
    dump_scene(make_spec(nodes=21, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=0.2, max_iter=30,
                         direction=direction), p)
    return p


@pytest.fixture
def data(tmp_path):
    """(scene file, data folder with measured.csv) for the rod of :func:`scene` at TRUTH."""
    path = scene(tmp_path)
    meas, _ = synthetic(load_scene(path), PARAMS, [math.log(1.3), 0.5])
    folder = tmp_path / "data"
    folder.mkdir()
    write_csv(folder / "measured.csv", meas)
    return path, folder


def test_fit_job_recovers_the_parameters_and_says_its_progress(data):
    path, folder = data
    seen = []
    job = FitJob(load_scene(path), folder / "measured.csv", PARAMS, notify=lambda: seen.append(1))
    assert job.progress() == "fit: not started"
    job.start()
    assert job.join(600) and job.state == "done", job.error
    res = job.result
    for k, v in TRUTH.items():
        assert res.params[k] == pytest.approx(v, rel=0.02), res.params
    assert len(job.history) == res.iterations >= 2 and len(seen) == len(job.history) + 1
    assert min(r for _, r in job.history) == pytest.approx(res.rms_m, rel=1e-9)
    assert job.progress().startswith(f"done · evaluation {len(job.history)} of at most 30")
    for k, v in TRUTH.items():   # the page's lines: "- name = value ± error"
        got = re.search(rf"- {k} = ([0-9.e+-]+) ± ([0-9.e+-]+)", job.table())
        assert got and float(got.group(1)) == pytest.approx(v, rel=0.02) and float(got.group(2)) > 0
    tr = res.track
    assert tr.node_pos.shape == (tr.t.size, 21, 3) and tr.measured.shape == tr.predicted.shape
    # the residual drawn is measured - fitted at the measured points: the fit's own residual (RMS ≈ the noise)
    assert float(np.sqrt(np.mean((tr.measured - tr.predicted) ** 2))) == pytest.approx(res.rms_m, rel=1e-9)
    nodes, meas, pred, tm = overlay_at(tr, 0.52)
    assert tm == pytest.approx(0.5333333, abs=1e-6)   # the nearest measurement time (30 Hz)
    assert meas.shape == (5, 3) and np.array_equal(meas, tr.measured[tr.measured_t == tm])
    np.testing.assert_array_equal(nodes, tr.node_pos[26])  # step 26 of dt 0.02 s


def test_stop_keeps_the_best_so_far(data):
    path, folder = data
    box = {}
    job = FitJob(load_scene(path), folder / "measured.csv", PARAMS, max_evaluations=50,
                 notify=lambda: box["job"].stop() if len(box["job"].history) >= 2 else None)
    box["job"] = job
    job.start()
    assert job.join(600)
    assert job.state == "stopped" and job.result is not None and job.result.interrupted
    assert len(job.history) == 2
    assert job.result.rms_m == pytest.approx(min(r for _, r in job.history), rel=1e-9)
    assert job.progress().startswith("stopped: best so far kept")


def test_a_fit_that_breaks_ends_failed_with_the_reason(data, capfd):
    """An error the fit does not expect (a defect) ends the job "failed" with its type and message, and its traceback
    on stderr: the panel never shows "running" for ever."""
    path, folder = data
    seen = []
    job = FitJob(load_scene(path), folder / "measured.csv", PARAMS, notify=lambda: seen.append(job.state))

    def broken(k, rms, values):
        raise RuntimeError("kernel said no")

    job._on_eval = broken
    job.start()
    assert job.join(600)
    assert job.state == "failed" and job.error == "RuntimeError: kernel said no" and job.result is None
    assert seen[-1] == "failed" and job.progress() == "⚠ fit failed: RuntimeError: kernel said no"
    assert "Traceback" in capfd.readouterr().err


def test_bad_requests_and_bad_data_are_refused_by_name(data, tmp_path):
    path, folder = data
    spec = load_scene(path)
    with pytest.raises(F.FitError, match="tick at least one parameter"):
        FitJob(spec, folder / "measured.csv", [])
    with pytest.raises(F.FitError, match="unknown parameter 'stiffness'"):
        FitJob(spec, folder / "measured.csv", ["stiffness"])
    bad = folder / "bad.csv"
    bad.write_text("t,s,x,y,z\n0,0.5,0,0,0\n0.1,0.5,nan,0,0\n")
    with pytest.raises(F.FitError, match=r"bad\.csv:3: x = .nan. is not finite"):
        FitJob(spec, bad, PARAMS)


def test_data_files_are_read_only_inside_the_data_folder(data, tmp_path):
    _, folder = data
    (folder / "sub").mkdir()
    (folder / "sub" / "more.npz").write_bytes(b"")
    (folder / "notes.txt").write_text("x")
    outside = tmp_path / "outside.csv"
    outside.write_text("t,s,x,y,z\n")
    os.symlink(outside, folder / "link.csv")
    files = Folders.create(scenes_dir=tmp_path / "scenes", recordings_dir=tmp_path / "rec", data_dir=folder)
    try:
        assert files.data_files() == ["measured.csv", "sub/more.npz"]
        assert files.data_file("sub/more.npz") == folder / "sub" / "more.npz"
        for bad in ("../outside.csv", "/etc/passwd", "link.csv", "notes.txt", "missing.csv", "sub\\more.npz", 3):
            with pytest.raises(FileAccessError, match="choose a data file from the list"):
                files.data_file(bad)
    finally:
        files.cleanup()


def test_fit_tab_fits_draws_and_applies_as_a_new_scene(data, tmp_path):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    path, folder = data
    scenes = tmp_path / "scenes"
    app = WorkbenchApp(Workbench.from_path(path), port=0, env_map=False, wait_for_browser=False,
                       scenes_dir=scenes, recordings_dir=tmp_path / "rec", data_dir=folder).start()
    try:
        panel = app.fit
        assert tuple(panel.data.options) == ("measured.csv",)
        assert panel.apply() is None and "run a fit first" in panel.msg.content
        assert panel.start("../outside.csv", PARAMS) is None and "choose a data file" in panel.msg.content
        job = panel.start("measured.csv", PARAMS)
        assert job is not None and job.join(600) and job.state == "done", job.error
        wait_for(lambda: "- youngs_modulus = " in panel.result.content, what="the result")
        assert panel.status.content.startswith("done")
        k, r = panel.loss.data
        assert list(k) == [h[0] for h in job.history] and np.allclose(r, [h[1] * 1e3 for h in job.history])
        assert panel._nodes is not None                      # fitted rod, measured points, residuals drawn
        assert panel.time.max == pytest.approx(float(job.result.track.t[-1]))
        panel.show.value = False
        wait_for(lambda: panel._nodes is None, what="the drawing removed")
        (scenes / "rod_3d_fitted.toml").parent.mkdir(exist_ok=True)
        (scenes / "rod_3d_fitted.toml").write_text("# a user's file: never replaced\n")
        out = panel.apply()
        assert out == scenes / "rod_3d_fitted_2.toml" and "applied" in panel.msg.content
        assert (scenes / "rod_3d_fitted.toml").read_text() == "# a user's file: never replaced\n"
        assert app.wb.scene_path == out
        fitted = load_scene(out)
        assert fitted.rod.youngs_modulus == pytest.approx(TRUTH["youngs_modulus"], rel=0.02)
        assert fitted.sim.damping == pytest.approx(TRUTH["damping"], rel=0.02)
    finally:
        app.stop()
    assert panel.loss is None and panel._nodes is None  # the session's end removes the fit's curve and drawing
