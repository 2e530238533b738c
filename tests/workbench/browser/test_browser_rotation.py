"""Real browser: the selected obstacle's rotation can be typed as roll, pitch, yaw [deg]; the obstacle, its mesh and
its gizmo turn; a gizmo turn shows in the fields; values out of range are refused by the server."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import expand_folder, wait_for
from workbench.session import obstacles as obst
from workbench.session.frame import quat_from_rpy_deg

pytestmark = pytest.mark.browser


def _row_inputs(page, label: str):
    lab = page.locator("label").filter(has_text=label).first
    return lab.locator("xpath=ancestor::div[.//input][1]//input")


def _same_rotation(q1, q2, atol=1e-6) -> bool:
    return abs(abs(float(np.dot(q1, q2))) - 1.0) < atol


def test_typed_rotation(wb_page):
    app, page = wb_page
    wb, ob, view = app.wb, app.obstacles, app.view
    wb.add_obstacle(obst.ObstacleEdit(kind="box", position=np.array([0.6, 0.4, 0.5]),
                                      half_extents=np.array([0.1, 0.05, 0.02])))
    wait_for(lambda: len(view.obstacle_nodes) == 1, what="box drawn")
    ob.select(0)  # as a click on it: an obstacle carries the gizmo only once selected
    wait_for(lambda: len(view.obstacle_nodes) == 1 and view.selected == 0, what="box selected")
    expand_folder(page, "Obstacles", "Delete obstacle")
    rot = _row_inputs(page, "Rotation [deg]")
    wait_for(lambda: rot.count() == 3 and rot.nth(2).input_value() not in ("",), what="rotation fields")
    rot.nth(2).fill("90")
    rot.nth(2).press("Enter")
    want = quat_from_rpy_deg((0.0, 0.0, 90.0))
    wait_for(lambda: _same_rotation(wb.obstacles[0].wxyz, want), what="typed yaw")
    assert _same_rotation(view.gizmo(0).wxyz, want) and _same_rotation(view.obstacle_nodes[0][0].wxyz, want)
    np.testing.assert_allclose(wb.obstacles[0].position, [0.6, 0.4, 0.5])  # the position is kept
    rot.nth(0).fill("30")
    rot.nth(0).press("Enter")
    want = quat_from_rpy_deg((30.0, 0.0, 90.0))
    wait_for(lambda: _same_rotation(wb.obstacles[0].wxyz, want), what="typed roll")
    # a gizmo turn (a drag in the page) shows in the fields
    q = quat_from_rpy_deg((10.0, -20.0, 45.0))
    app._on_gizmo(0, wb.obstacles[0].position, q)

    def shown() -> list[float]:
        try:
            return [float(rot.nth(i).input_value()) for i in range(3)]
        except ValueError:
            return [np.nan] * 3

    wait_for(lambda: np.allclose(shown(), [10.0, -20.0, 45.0], atol=1e-3), what="fields follow the gizmo")
    # out of range (a page sending what its inputs would not): refused, nothing moves
    before = wb.obstacles[0].wxyz.copy()
    ob.rotation.value = (500.0, 0.0, 0.0)
    assert "Rotation [deg]" in ob.msg.content and "⚠" in ob.msg.content
    np.testing.assert_allclose(wb.obstacles[0].wxyz, before)
    wait_for(lambda: np.allclose(shown(), [10.0, -20.0, 45.0], atol=1e-3), what="fields show the pose again")
    ob.rotation.value = (float("nan"), 0.0, 0.0)
    np.testing.assert_allclose(wb.obstacles[0].wxyz, before)
