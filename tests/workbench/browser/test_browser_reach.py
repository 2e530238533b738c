"""Reach in a real browser: the Teleop tab's "Reach" box puts a target gizmo at the tip; dragging it sets the
sliders by inverse statics and the live arm follows the target."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import WAIT_MS, drag_gizmo_x, expand_folder, newest_client, retry_until, wait_for
from workbench.panels.controls import REACH_GIZMO_SCALE

pytestmark = pytest.mark.browser


def test_dragging_the_reach_target_moves_the_arm_there(wb_page, shots_dir):
    app, page = wb_page
    wb, ctl = app.wb, app.controls
    wait_for(lambda: wb.frame_index > 3, what="sim running")
    wb.set_teleop_value(2, 0, 1.0)  # a bent arm (its tip inside the reachable ball, not on its edge)
    app.controls.sync_sliders()
    wait_for(lambda: np.hypot(*wb.tip[:2]) > 0.2, timeout=30, what="the arm bent")
    expand_folder(page, "Teleop", "Zero sliders")
    page.get_by_role("checkbox", name="Reach", exact=True).click()
    wait_for(lambda: ctl.reach_gizmo is not None, what="the reach target at the tip")
    tip0 = np.asarray(ctl.reach_gizmo.position, dtype=np.float64).copy()
    cam = newest_client(app).camera  # look at the tip from the front, close, so the gizmo's x arrow is large
    cam.position, cam.look_at = (tip0[0] + 0.2, tip0[1] - 1.0, tip0[2]), (tip0[0] + 0.2, tip0[1], tip0[2])
    wait_for(lambda: np.allclose(cam.position, (tip0[0] + 0.2, tip0[1] - 1.0, tip0[2]), atol=1e-3),
             what="camera moved")

    sign = -np.sign(tip0[0]) or -1.0  # towards the arm's axis: a target the arm can reach

    def drag() -> None:
        now = np.asarray(ctl.reach_gizmo.position, dtype=np.float64)
        drag_gizmo_x(page, newest_client(app), now, scale=REACH_GIZMO_SCALE,
                     dist=sign * 0.2 - (now[0] - tip0[0]))

    retry_until(drag, lambda: sign * (float(ctl.reach_gizmo.position[0]) - tip0[0]) > 0.12,
                what="the target dragged")
    target = np.asarray(ctl.reach_gizmo.position, dtype=np.float64).copy()
    # the sliders now hold the curvature for the target and the arm goes there
    wait_for(lambda: abs(wb.teleop.values[2, 0] - 1.0) > 0.05, what="sliders set by inverse statics")
    wait_for(lambda: np.linalg.norm(wb.tip - np.asarray(ctl.reach_gizmo.position)) < 0.02, timeout=60,
             what=f"the tip at the target {np.round(target, 3)} (tip {np.round(wb.tip, 3)})")
    wait_for(lambda: abs(ctl.sliders[0][0].value - round(float(wb.teleop.values[0, 0]), 2)) < 1e-9,
             what="the page's sliders show the values")
    (shots_dir / "workbench_reach.png").write_bytes(page.screenshot(timeout=WAIT_MS))
    page.get_by_role("checkbox", name="Reach", exact=True).click()
    wait_for(lambda: ctl.reach_gizmo is None, what="the target gone with Reach off")


def test_reach_refuses_a_non_finite_target(wb_page):
    app, _ = wb_page
    with pytest.raises(ValueError, match="3 finite numbers"):
        app.wb.reach_to([0.1, np.nan, 0.5])


def test_reach_frame_gives_the_target_the_tips_frame_and_rotation_rings(wb_page):
    """Ticking "Reach frame" in the page with Reach on puts the target back with its rotation rings, turned as the
    tip's frame (the pose inverse statics then holds, position and frame); unticked, the rings go."""
    from sim.geometry import quat_to_matrix

    app, page = wb_page
    wb, ctl = app.wb, app.controls
    wait_for(lambda: wb.frame_index > 3, what="sim running")
    expand_folder(page, "Teleop", "Zero sliders")
    page.get_by_role("checkbox", name="Reach", exact=True).click()
    wait_for(lambda: ctl.reach_gizmo is not None, what="the reach target at the tip")
    assert ctl.reach_gizmo.disable_rotations
    page.get_by_role("checkbox", name="Reach frame").click()
    wait_for(lambda: ctl.reach_gizmo is not None and not ctl.reach_gizmo.disable_rotations,
             what="the target with rotation rings")
    R = quat_to_matrix(np.asarray(ctl.reach_gizmo.wxyz, dtype=np.float64))
    assert np.abs(R - wb.tip_frame).max() < 0.05  # the tip's frame (the arm moves on a little meanwhile)
    page.get_by_role("checkbox", name="Reach frame").click()
    wait_for(lambda: ctl.reach_gizmo is not None and ctl.reach_gizmo.disable_rotations, what="the rings gone")
    page.get_by_role("checkbox", name="Reach", exact=True).click()
    wait_for(lambda: ctl.reach_gizmo is None, what="the target gone with Reach off")
