"""The Fit tab in a real browser: with a scene open and measured motion in the data folder, "Run fit" in the page fits
the scene's parameters (the result table lists them with their errors), the fitted rod is drawn with the measured
points, and "Apply as new scene" opens the fitted scene from the scenes folder."""
from __future__ import annotations

import math
import re

import pytest

from sim.scene.spec import load_scene
from tests.helpers.fit import synthetic, write_csv
from tests.workbench.panels.test_fit_panel import scene
from tools.browser import expand_folder, wait_for
from workbench.session.simbridge import builtin_spec

pytestmark = pytest.mark.browser


def test_run_fit_and_apply_from_the_page(wb_page, tmp_path):
    app, page = wb_page
    wb = app.wb
    path = scene(tmp_path)
    meas, _ = synthetic(load_scene(path), ["youngs_modulus", "damping"], [math.log(1.3), 0.5])
    folder = tmp_path / "data"
    folder.mkdir()
    write_csv(folder / "measured.csv", meas)
    old_data = app.files.data
    app.files.data = folder
    try:
        wb.load_scene(path)
        wb.set_playing(False)  # the fit needs no live motion (and runs sooner without it)
        app.refresh_rod_scene()
        app.fit.refresh_list()
        expand_folder(page, "Fit", "Run fit")
        page.get_by_role("button", name="Run fit").click()
        wait_for(lambda: app.fit.job is not None and app.fit.job.state == "done", what="the fit done")
        line = page.get_by_text(re.compile(r"youngs_modulus = [0-9.e+]+ ±"))
        line.first.wait_for(state="visible")
        value = float(re.search(r"youngs_modulus = ([0-9.e+]+)", line.first.inner_text()).group(1))
        assert value == pytest.approx(1.3e6, rel=0.02)
        assert app.fit._nodes is not None
        page.get_by_role("button", name="Apply as new scene").click()
        wait_for(lambda: "applied" in app.fit.msg.content, what="the fitted scene applied")
        assert wb.scene_path is not None and wb.scene_path.parent == app.files.scenes
        assert load_scene(wb.scene_path).rod.youngs_modulus == pytest.approx(1.3e6, rel=0.02)
        page.get_by_text("applied: opened the fitted scene").first.wait_for(state="visible")
    finally:
        page.get_by_text("Run", exact=True).first.click()  # the next tests find their controls from the first tab
        app.fit.close()
        app.fit.job = None
        app.files.data = old_data
        app.fit.refresh_list()
        with wb.lock:
            wb._replace_spec(builtin_spec(), keep_state=False)
            wb.scene_path = None
        wb.reset()
        app.refresh_rod_scene()
