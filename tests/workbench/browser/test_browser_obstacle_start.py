"""Real browser, a session opened on the default scene (five obstacles, a floor plane among them): at the start no
obstacle is selected (no gizmo; the Position/Rotation/Size fields are disabled rather than showing another obstacle's
values) and picking one shows its own values; a policy run puts no gizmo on its obstacles; "Add obstacle" puts the
new one beside the rod, in the start view left of the side panel, clear of the rod and of the other obstacles (the
floor plane only rules out what lies below it), and selects it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import expect

from tools.browser import expand_folder, newest_client, open_page, project, wait_for
from workbench.session.obstacles import bounding_radius, surface_distance

pytestmark = pytest.mark.browser

DEFAULT = Path(__file__).resolve().parents[3] / "assets" / "scenes" / "default.toml"

#: whether the page's scene has a transform gizmo
GIZMO_JS = "() => Boolean(window.__viserSceneTree?.getState()?.['/obstacle_gizmo']?.message)"


@pytest.fixture
def default_app(browser, tmp_path):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    app = WorkbenchApp(Workbench.from_path(DEFAULT), port=0, env_map=False, recordings_dir=tmp_path / "rec",
                       scenes_dir=tmp_path / "scenes").start()
    page = open_page(browser, app, width=960, height=640)
    try:
        yield app, page
    finally:
        page.close()
        app.stop()


def _row_inputs(page, label: str):
    lab = page.locator("label").filter(has_text=label).first
    return lab.locator("xpath=ancestor::div[.//input][1]//input")


def _shown(inputs) -> list[float]:
    try:
        return [float(inputs.nth(i).input_value()) for i in range(3)]
    except ValueError:
        return [float("nan")] * 3


def test_fields_and_gizmo_at_start(default_app):
    app, page = default_app
    wb, view = app.wb, app.view
    assert [e.name for e in wb.obstacles][:2] == ["bar", "ball"]
    wb.set_playing(False)  # the fields and the gizmo on a still rod (a moving one draws many frames)
    expand_folder(page, "Obstacles", "Add obstacle")
    # nothing selected yet: no gizmo, and the fields cannot show (or edit) an obstacle that is not selected
    expect(page.get_by_label("Selected")).to_have_value("(none)")
    pos, size = _row_inputs(page, "Position [m]"), _row_inputs(page, "Size [m]")
    for i in range(3):
        expect(pos.nth(i)).to_be_disabled()
        expect(size.nth(i)).to_be_disabled()
    assert view.selected is None and not page.evaluate(GIZMO_JS)
    # picking "0: bar" shows the bar's own values (a capsule: radius, length)
    page.get_by_label("Selected").click()
    page.get_by_role("option", name="0: bar", exact=True).click()
    bar = wb.obstacles[0]
    wait_for(lambda: np.allclose(_shown(pos), bar.position, atol=1e-3), what="the bar's position in the fields")
    wait_for(lambda: np.allclose(_shown(size), (bar.radius, bar.length, bar.radius), atol=1e-3),
             what="the bar's size in the fields")
    np.testing.assert_allclose(bar.position, (0.35, 0.0, 0.55), atol=1e-9)
    expect(pos.nth(0)).to_be_enabled()
    wait_for(lambda: view.selected == 0 and page.evaluate(GIZMO_JS), what="the gizmo on the bar")


def test_no_gizmo_in_a_policy_run_and_new_obstacles_in_view(default_app):
    app, page = default_app
    wb, view = app.wb, app.view
    app.policy.start_task("random_obstacles_3d", "zero")
    wait_for(lambda: wb.mode == "policy" and len(view.obstacle_nodes) == len(wb.obstacles) > 0, timeout=120,
             what="the task's obstacles drawn")
    wait_for(lambda: wb.frame_index > 5, timeout=120, what="the policy running")
    assert view.selected is None and not page.evaluate(GIZMO_JS)
    wb.stop_policy()
    wait_for(lambda: wb.mode == "teleop" and len(view.obstacle_nodes) == len(wb.obstacles) == 5, what="back to teleop")
    assert view.selected is None and not page.evaluate(GIZMO_JS)
    # Add obstacle: in the start view, beside the rod, clear of everything, selected (its gizmo)
    expand_folder(page, "Obstacles", "Add obstacle")
    app.view.set_camera("iso")
    cam = newest_client(app).camera
    wait_for(lambda: np.allclose(cam.position, app.server.initial_camera.position, atol=1e-3), what="start view")
    page.get_by_role("button", name="Add obstacle").click()
    wait_for(lambda: len(wb.obstacles) == 6 and len(view.obstacle_nodes) == 6, what="the new obstacle")
    new, others = wb.obstacles[5], wb.obstacles[:5]
    x = np.asarray(wb.live.state.node_pos[0], np.float64)
    r = bounding_radius(new)
    assert np.min(np.linalg.norm(x - new.position, axis=1)) > r + wb.live.rod_radius
    for o in others:
        assert surface_distance(o, new.position[None])[0] > r, f"{new.position} overlaps {o.name}"
    assert np.min(np.linalg.norm(x - new.position, axis=1)) < 0.6  # beside the rod, not across the room
    box = page.locator("canvas").first.bounding_box()
    u, v = project(cam, new.position[None], box["width"], box["height"])[0]
    panel_left = page.get_by_role("button", name="Add obstacle").bounding_box()["x"] - box["x"]
    assert 0 < u < panel_left and 0 < v < box["height"], f"new obstacle drawn at ({u:.0f}, {v:.0f}) px"
    wait_for(lambda: view.selected == 5 and page.evaluate(GIZMO_JS), what="the new obstacle selected")
    expect(page.get_by_label("Selected")).to_have_value("5: sphere")
