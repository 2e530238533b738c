"""Real browser: the page is organised in tabs with the status line above them, every control has a hint, 2-D
tasks show only their in-plane sliders and face their plane, and the camera presets move the view."""
from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import expect

from tools.browser import WAIT_MS, expand_folder, newest_client, project, slider_root, wait_for
from workbench.panels.controls import TABS, slider_label

pytestmark = pytest.mark.browser


def _assert_in_view(client, pts) -> None:
    """Every point inside the page's camera image (the camera as the page reported it)."""
    cam = client.camera
    w, h = cam.image_width, cam.image_height
    uv = project(cam, np.asarray(pts, np.float64), w, h)
    assert (uv >= 0).all() and (uv[:, 0] <= w).all() and (uv[:, 1] <= h).all(), f"{uv} outside {w} x {h}"


def test_tabs_with_status_always_visible(wb_page):
    app, page = wb_page
    app.wb.set_playing(False)  # the page alone is tested: a still rod draws no frames
    for name in TABS:
        page.get_by_role("tab", name=name, exact=True).click()
        expect(page.get_by_role("tab", name=name, exact=True)).to_have_attribute("aria-selected", "true")
        # the status line (mode, frame, real-time factor) stays on screen whatever the tab
        expect(page.get_by_text("real-time factor", exact=False).first).to_be_visible()


def test_every_control_has_a_hint_and_units(wb_page):
    app, page = wb_page
    app.wb.set_playing(False)  # the page alone is tested: a still rod draws no frames
    handles = [app.controls.speed, app.controls.force_scale, app.controls.color_by, app.controls.mode,
               app.policy.task, app.policy.policy, app.policy.rewind, app.replay.timeline, app.replay.speed,
               app.obstacles.kind, app.obstacles.selected, *(s for row in app.controls.sliders for s in row)]
    for h in handles:
        assert h.hint, f"{h.label} has no hint"
    assert slider_label(2, 0) == "κ1 at node 10 [rad]" and "[× real time]" in app.controls.speed.label
    # the hint shows in the page (viser draws it as a tooltip of the input, after 0.5 s of hovering)
    expand_folder(page, "Teleop", "Zero sliders")
    slider_root(page, slider_label(2, 0)).hover()
    expect(page.get_by_text("around node 10", exact=False).first).to_be_visible(timeout=WAIT_MS)


def test_planar_task_and_camera_presets(wb_page):
    app, page = wb_page
    wb = app.wb
    client = newest_client(app)
    app.policy.start_task("follow_target_2d", "zero")
    wait_for(lambda: wb.mode == "policy" and wb.policy.planar, timeout=60, what="2-D task")
    # the camera faces the x-z plane of the task
    wait_for(lambda: app.view.camera[0] == "front" and np.allclose(client.camera.position, app.view.camera[1], atol=1e-3),
             what="front camera")
    # fitted to the task's arm: every node inside the page's view
    _assert_in_view(client, wb.frame().node_pos)
    expand_folder(page, "Teleop", "Zero sliders")
    expect(page.get_by_text(slider_label(2, 0), exact=True)).to_be_visible()
    expect(page.get_by_text(slider_label(2, 1), exact=True)).to_have_count(0)  # no out-of-plane bend
    expect(page.get_by_text(slider_label(2, 2), exact=True)).to_have_count(0)  # no twist
    # the presets (Display tab) move the camera of the page
    expand_folder(page, "Display", "top")
    page.get_by_role("button", name="top", exact=True).click()
    wait_for(lambda: app.view.camera[0] == "top" and np.allclose(client.camera.position, app.view.camera[1], atol=1e-3),
             what="top camera")
    page.get_by_role("button", name="side", exact=True).click()
    wait_for(lambda: app.view.camera[0] == "side" and np.allclose(client.camera.position, app.view.camera[1], atol=1e-3),
             what="side camera")
    # back to a 3-D scene: every slider again, oblique view
    wb.stop_policy()
    wait_for(lambda: app.view.camera[0] == "iso" and np.allclose(client.camera.position, app.view.camera[1], atol=1e-3),
             what="iso camera")
    _assert_in_view(client, wb.frame().node_pos)
    expand_folder(page, "Teleop", "Zero sliders")
    expect(page.get_by_text(slider_label(2, 2), exact=True)).to_be_visible()
