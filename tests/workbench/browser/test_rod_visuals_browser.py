"""Real browser: the rod is one smooth tube whose per-vertex colours show the chosen quantity (red where κ1 > 0,
blue where κ1 < 0), never missing from a frame while it streams; control points, rest shape, tip trail and the tip
frame beside the IK target's frame are toggled from the Display tab."""
from __future__ import annotations

import io

import numpy as np
import pytest

from tools.browser import canvas_png, expand_folder, newest_client, project, retry_until, wait_for
from workbench.view import place_camera

pytestmark = pytest.mark.browser


def _rgb(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)


def _patch(img: np.ndarray, uv, r: int = 2) -> np.ndarray:
    u, v = int(round(uv[0])), int(round(uv[1]))
    return img[max(v - r, 0):v + r + 1, max(u - r, 0):u + r + 1].reshape(-1, 3)


def _reddish(p) -> bool:
    return bool(np.median(p[:, 0] - p[:, 2]) > 40)


def _bluish(p) -> bool:
    return bool(np.median(p[:, 2] - p[:, 0]) > 40)


def _settle_bent(app) -> np.ndarray:
    """Bend the rod one way near its base and the other way further out; returns the paused node positions."""
    wb = app.wb
    wb.set_teleop_value(0, 0, 1.2)
    wb.set_teleop_value(1, 0, 1.2)
    wb.set_teleop_value(3, 0, -1.6)
    wb.set_teleop_value(4, 0, -1.6)
    app.controls.sync_sliders()
    f = wb.frame_index
    wait_for(lambda: wb.frame_index > f + 60, timeout=60, what="the rod to bend")
    wb.set_playing(False)
    app.controls.set_quiet(app.controls.playing, False)
    app.request_render()
    with wb.lock:
        return np.asarray(wb.live.state.node_pos[0], np.float64).copy()


def _look_at_rod(app, x: np.ndarray):
    cam = newest_client(app).camera
    look = x.mean(axis=0)
    span = float(np.ptp(x, axis=0).max())
    # look along the normal of the plane the bent rod lies in (a face-on view of the bend)
    u, s, vt = np.linalg.svd(x - look)
    n = vt[2] if abs(vt[2][1]) > 0.1 else np.array([0.0, -1.0, 0.0])
    pos = look + n * (1.6 * span + 0.4)
    right = np.cross(look - pos, [0.0, 0.0, 1.0])
    shift = right / np.linalg.norm(right) * 0.45 * (1.6 * span + 0.4)  # the rod left of centre, clear of the panel
    pos, look = pos + shift, look + shift
    place_camera(newest_client(app), tuple(pos), tuple(look))
    wait_for(lambda: np.allclose(cam.position, pos, atol=1e-3) and np.allclose(cam.look_at, look, atol=1e-3),
             what="camera moved")
    return cam


def test_tube_colours_and_no_missing_frames(wb_page):
    app, page = wb_page
    view = app.view
    expand_folder(page, "Display", "top")
    page.get_by_label("Colour by").click()
    page.get_by_role("option", name="κ1", exact=True).click()
    wait_for(lambda: view.overlays.color_by == "κ1", what="colour by κ1")
    view.overlays.control_points = False  # the beads would cover some rings (their checkbox: test_display_toggles)
    x = _settle_bent(app)
    wait_for(lambda: view.rod.last_mesh is not None and not view.rod.tube.pending, what="tube shown")
    mesh = view.rod.last_mesh
    n = len(x)
    assert mesh.vertices.shape[0] == n * view.rod.sides + 2 * (view.rod.sides + 1)  # one mesh for the whole rod
    cols = mesh.colors[: n * view.rod.sides: view.rod.sides].astype(int)  # the colour of each ring
    red = [i for i in range(2, n - 2) if cols[i, 0] - cols[i, 2] > 80]
    blue = [i for i in range(2, n - 2) if cols[i, 2] - cols[i, 0] > 80]
    assert red and blue, "the bend should give both signs of κ1"
    cam = _look_at_rod(app, x)
    box = page.locator("canvas").first.bounding_box()
    uv = project(cam, x, box["width"], box["height"])

    def shows_colours() -> bool:
        img = _rgb(canvas_png(page))
        r = np.mean([_reddish(_patch(img, uv[i])) for i in red])
        b = np.mean([_bluish(_patch(img, uv[i])) for i in blue])
        return r >= 0.7 and b >= 0.7  # (highlights and the tip frame's axes may cover a ring or two)

    wait_for(shows_colours, timeout=30, interval=0.5, what="red and blue parts of the tube in the page")
    # streaming: a new mesh every frame, the tube is in every screenshot (two GLB nodes take turns); with shadows (the
    # page's default) — without them a frame can lack the tube after the Plots tab has drawn (a known defect)
    app.wb.set_playing(True)
    app.controls.set_quiet(app.controls.playing, True)
    probe = red[len(red) // 2]
    for _ in range(6):
        img = _rgb(canvas_png(page))
        assert _reddish(_patch(img, uv[probe], r=3)), "the tube was missing from a frame"
    assert sum(h.visible for h in view.rod.tube.nodes) == 1
    view.overlays.control_points = True
    app.controls.color_by.value = "curvature"


def test_display_toggles(wb_page):
    app, page = wb_page
    view, rod = app.view, app.view.rod
    expand_folder(page, "Display", "top")
    x = _settle_bent(app)
    from workbench.session.teleop import CONTROL_NODES

    wait_for(lambda: rod.controls.visible and rod.rest.visible, what="control points and rest shape shown")
    wait_for(lambda: view.last_frame.time == pytest.approx(float(np.asarray(app.wb.live.state.time)[0])),
             what="the paused frame drawn")
    x = view.last_frame.node_pos
    np.testing.assert_allclose(rod.controls.batched_positions, x[list(CONTROL_NODES)], atol=1e-5)
    rest, _nodes = rod.rest_nodes, rod.control_nodes
    assert rest is not None and np.linalg.norm(rest - x, axis=1).max() > 0.05  # the rest shape is not the bent rod
    for label, handle, attr in (("Control points", rod.controls, "control_points"), ("Rest shape", rod.rest,
                                "rest_shape"), ("Tip trail", rod.trail, "trail"), ("Tip frame", rod.tip_frame,
                                                                               "tip_frame")):
        page.get_by_label(label).click()
        wait_for(lambda a=attr: not getattr(view.overlays, a), what=f"{label} off")
        wait_for(lambda h=handle: not h.visible, what=f"{label} hidden")
        page.get_by_label(label).click()
        wait_for(lambda a=attr: getattr(view.overlays, a), what=f"{label} on")
    # shadows: on by default, turned off and on again from the page
    assert view.shadows
    page.get_by_label("Shadows").click()
    wait_for(lambda: not view.shadows, what="shadows off")
    page.get_by_label("Shadows").click()
    wait_for(lambda: view.shadows, what="shadows on")
    # the trail: the tip's last 2 s while it moves, cleared by a reset
    app.wb.set_teleop_value(2, 1, 1.5)
    app.wb.set_playing(True)
    wait_for(lambda: len(rod.trail_positions()) > 20 and rod.trail.visible, timeout=60, what="a trail")
    tr = rod.trail_positions()
    assert np.linalg.norm(tr[-1] - tr[0]) > 1e-3
    assert rod.trail_points[-1][0] - rod.trail_points[0][0] <= 2.0 + 1e-9
    # paused first, so the reset's frame 0 holds until it is seen (playing, it lasts a second of wall clock, which
    # the test's own round trip through the browser can outlast on a busy machine)
    app.wb.set_playing(False)
    expand_folder(page, "Run", "Step")
    page.get_by_role("button", name="Reset", exact=True).click()
    wait_for(lambda: app.wb.frame_index == 0, what=lambda: f"reset (frame {app.wb.frame_index})")
    wait_for(lambda: len(rod.trail_points) == 1 and rod.trail_points[0][0] == 0.0,
             what=lambda: f"trail cleared on reset ({len(rod.trail_points)} points)")
    app.wb.set_playing(True)  # and it grows again from the reset's frame
    wait_for(lambda: len(rod.trail_points) > 3, what="a new trail")


def test_tip_frame_beside_the_ik_target_frame(wb_page):
    app, page = wb_page
    wb, view = app.wb, app.view
    app.policy.start_task("ik4d", "zero")
    try:
        wait_for(lambda: wb.mode == "policy" and view.target_frame.visible and view.rod.tip_frame.visible
                 and view.last_frame is not None and view.last_frame.target_wxyz is not None,
                 timeout=120, what="IK task with both frames")
        # each drawn frame with the tip frame as the view left it, read in the drawing thread right after the view
        # drew it. Another thread may draw at the same moment (a render requested from the page), so the paused
        # session is redrawn until a frame's own tip frame is read: the check is that the view draws it right
        drawn: list = []

        def seen(fr) -> None:
            drawn.append((fr, np.array(view.rod.tip_frame.position), np.array(view.rod.tip_frame.wxyz)))

        def at_its_tip(entry) -> bool:
            # viser skips a pose within np.allclose's default tolerances of the one it holds, so a paused rod that
            # crept by less than that since the last redraw keeps the frame where it was: compare as viser does
            fr, position, _ = entry
            return bool(np.allclose(position, fr.node_pos[-1]))

        app.render_hooks.append(seen)
        try:
            wb.set_playing(False)
            n = len(drawn)
            retry_until(app.request_render, lambda: any(at_its_tip(e) for e in drawn[n:]), attempt_s=2.0,
                        what=lambda: (f"a redraw of the paused session with the tip frame at its tip ({len(drawn) - n} "
                                      f"redraws, sim thread error {app.thread.error!r})"))
        finally:
            app.render_hooks.remove(seen)
        fr, position, wxyz = next(e for e in drawn[n:] if at_its_tip(e))
        assert fr.target_wxyz is not None
        from sim.geometry import quat_to_matrix

        R = quat_to_matrix(wxyz)
        np.testing.assert_allclose(R[:, 0], fr.m1[-1], atol=1e-6)
        np.testing.assert_allclose(R[:, 2], (fr.node_pos[-1] - fr.node_pos[-2]) / np.linalg.norm(
            fr.node_pos[-1] - fr.node_pos[-2]), atol=1e-6)
        assert view.rod.control_nodes == tuple(wb.policy.core.converter.cfg.control_points)
    finally:
        wb.stop_policy()
