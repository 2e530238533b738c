"""Real browser: new obstacles are placed clear of the rod and of each other, a click on an obstacle selects it
(one gizmo, on the selected obstacle only; the "Selected" dropdown follows and drives the selection), its position
and size can be typed, and an obstacle on the rod's rest shape gives a warning."""
from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import expect

from tools.browser import expand_folder, newest_client, project, retry_until, wait_for
from workbench.session.obstacles import bounding_radius

pytestmark = pytest.mark.browser


def _row_inputs(page, label: str):
    lab = page.locator("label").filter(has_text=label).first
    return lab.locator("xpath=ancestor::div[.//input][1]//input")


def test_select_by_click_dropdown_and_typed_pose(wb_page):
    app, page = wb_page
    wb, ob, view = app.wb, app.obstacles, app.view
    wb.set_playing(False)  # obstacles are placed, picked and typed on a still rod (a moving one draws many frames)
    expand_folder(page, "Obstacles", "Add obstacle")
    page.get_by_role("button", name="Add obstacle").click()
    wait_for(lambda: len(wb.obstacles) == 1 and len(view.obstacle_nodes) == 1, what="first obstacle")
    page.get_by_role("button", name="Add obstacle").click()
    wait_for(lambda: len(wb.obstacles) == 2 and len(view.obstacle_nodes) == 2, what="second obstacle")
    a, b = wb.obstacles
    x = wb.live.state.node_pos[0]
    for e in (a, b):  # clear of the rod ...
        assert np.min(np.linalg.norm(x - e.position, axis=1)) > bounding_radius(e) + wb.live.rod_radius
    assert np.linalg.norm(a.position - b.position) > bounding_radius(a) + bounding_radius(b)  # ... and of each other
    # the new one is selected and carries the only gizmo
    wait_for(lambda: view.selected == 1, what="new obstacle selected")
    assert np.allclose(view.gizmo(1).position, b.position)
    with pytest.raises(KeyError):
        view.gizmo(0)
    # click obstacle 0 in the 3-D view (camera in front of it, looking along +y)
    cam = newest_client(app).camera
    look = a.position.copy()
    cam.position, cam.look_at = tuple(look + np.array([0.0, -1.0, 0.0])), tuple(look)
    wait_for(lambda: np.allclose(cam.position, look + np.array([0.0, -1.0, 0.0]), atol=1e-3), what="camera moved")
    box = page.locator("canvas").first.bounding_box()
    uv = project(cam, np.stack([a.position, b.position]), box["width"], box["height"]) + [box["x"], box["y"]]
    assert np.linalg.norm(uv[0] - uv[1]) > 40, "the two obstacles overlap on screen"
    # a software-GL page may not have drawn the new camera at the first click
    retry_until(lambda: page.mouse.click(*uv[0]), lambda: view.selected == 0, what="click to select obstacle 0")
    assert view.selected == 0 and np.allclose(view.gizmo(0).position, a.position)
    expect(page.get_by_label("Selected")).to_have_value("0: sphere")
    # the dropdown selects too
    page.get_by_label("Selected").click()
    page.get_by_role("option", name="1: sphere", exact=True).click()
    wait_for(lambda: view.selected == 1, what="dropdown to select obstacle 1")
    assert np.allclose(view.gizmo(1).position, b.position)
    # type a position and a size for the selected obstacle
    pos = _row_inputs(page, "Position [m]")

    def shown_x() -> float:
        try:
            return float(pos.nth(0).input_value())
        except ValueError:
            return float("nan")

    # the fields show the selected obstacle before typing (else the page's update could overwrite the typed value)
    wait_for(lambda: abs(shown_x() - b.position[0]) < 1e-3, what="position field of obstacle 1")
    pos.nth(0).fill("0.7")
    pos.nth(0).press("Enter")
    wait_for(lambda: wb.obstacles[1].position[0] == pytest.approx(0.7), what="typed x")
    wait_for(lambda: np.allclose(view.gizmo(1).position, wb.obstacles[1].position), what="gizmo follows")
    size = _row_inputs(page, "Size [m]")
    size.nth(0).fill("0.05")
    size.nth(0).press("Enter")
    wait_for(lambda: wb.obstacles[1].radius == pytest.approx(0.05), timeout=30, what="typed radius")
    # an obstacle on the rod's rest shape: a warning in the page
    assert ob.warning.content == ""
    rest = np.asarray(wb.live.model.rest_node_pos, np.float64).reshape(-1, 3)[10]
    for i, v in enumerate(rest):
        pos.nth(i).fill(f"{v:.3f}")
        pos.nth(i).press("Enter")
    wait_for(lambda: np.allclose(wb.obstacles[1].position, rest, atol=2e-3), what="obstacle moved onto the rod")
    wait_for(lambda: "rod starts inside" in ob.warning.content, timeout=20, what="overlap warning")
    expect(page.get_by_text("rod starts inside", exact=False).first).to_be_visible()
