"""Real browser against a real workbench server: the page renders and the teleop sliders drive
the rod on the server."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import WAIT_MS, canvas_variance, expand_folder, slider_thumb, wait_for

pytestmark = pytest.mark.browser


def test_page_renders_rod(wb_page, shots_dir):
    app, page = wb_page
    # a blank WebGL canvas has (almost) zero pixel variance; poll: the first frames may be empty
    wait_for(lambda: canvas_variance(page) > 50.0, timeout=30, what="3D view to show the scene")
    (shots_dir / "workbench_start.png").write_bytes(page.screenshot(timeout=WAIT_MS))


def test_teleop_slider_moves_tip(wb_page, shots_dir):
    app, page = wb_page
    wb = app.wb
    wait_for(lambda: wb.frame_index > 3, what="sim running")
    tip0 = wb.tip.copy()
    expand_folder(page, "Teleop", "Zero sliders")
    th = slider_thumb(page, "κ1 at node 10 [rad]")
    th.focus()
    th.press("End")  # slider to its maximum (+2)
    wait_for(lambda: wb.teleop.values[2, 0] == pytest.approx(2.0), what="slider value on the server")
    # the rod bends: the tip moves sideways by more than 10 cm and drops
    wait_for(lambda: np.hypot(*(wb.tip - tip0)[:2]) > 0.1, timeout=20, what="tip to move")
    assert wb.tip[2] < tip0[2] - 0.01
    th = slider_thumb(page, "κ2 at node 18 [rad]")
    th.focus()
    th.press("Home")
    wait_for(lambda: wb.teleop.values[4, 1] == pytest.approx(-2.0), what="second slider")
    app.controls.frames.value = True  # material frames overlay for the screenshot
    wait_for(lambda: app.view.frames.visible, what="frames overlay")
    (shots_dir / "workbench_teleop.png").write_bytes(page.screenshot(timeout=WAIT_MS))
    app.controls.frames.value = False
