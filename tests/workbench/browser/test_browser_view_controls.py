"""Real browser: "Fit view" frames the scene from the direction the page looks from (its orbit kept, distance and
look-at fitted; other pages keep their views), and "Plot height" draws every plot taller."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import expand_folder, newest_client, wait_for
from workbench.view.scene import fit_camera_along, place_camera

pytestmark = pytest.mark.browser


def test_fit_view_keeps_the_direction_and_frames_the_scene(wb_page):
    app, page = wb_page
    wb, view = app.wb, app.view
    wb.set_playing(False)
    app.request_render()
    wait_for(lambda: view.last_frame.time == pytest.approx(float(np.asarray(wb.live.state.time)[0])),
             what="the paused frame drawn")
    client = newest_client(app)
    cam = client.camera
    d = np.array([0.3, -1.0, 0.4])
    far_look = np.array([2.0, 1.0, -0.5])
    place_camera(client, tuple(far_look + 12.0 * d), tuple(far_look))  # far off and looking at nothing
    wait_for(lambda: np.allclose(cam.look_at, far_look, atol=1e-3), what="the page's camera moved away")
    pos, look = fit_camera_along(d, view.fit_points())
    expand_folder(page, "Display", "Fit view")
    page.get_by_role("button", name="Fit view", exact=True).click()

    def framed() -> bool:  # (1 mm: the page's orbit controls may settle a camera set from the server by a hair)
        return np.allclose(cam.look_at, look, atol=1e-3) and np.allclose(cam.position, pos, atol=1e-3)

    wait_for(framed, what=lambda: f"the scene framed (camera {np.round(cam.position, 4)} -> "
                                  f"{np.round(cam.look_at, 4)}, expected {np.round(pos, 4)} -> {np.round(look, 4)})")
    off = np.asarray(cam.position) - np.asarray(cam.look_at)
    np.testing.assert_allclose(off / np.linalg.norm(off), d / np.linalg.norm(d), atol=1e-3)  # the same direction
    assert np.linalg.norm(np.asarray(cam.look_at) - far_look) > 1.0  # it moved: from looking at nothing to the rod
    # the rod is in front of the camera, at the framed distance: its points lie within the field of view
    rest = np.asarray(view.last_frame.node_pos)
    centre = 0.5 * (rest.min(axis=0) + rest.max(axis=0))
    assert np.linalg.norm(np.asarray(look) - centre) < np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))


def test_plot_height_draws_every_plot_taller(wb_page):
    app, page = wb_page
    plots = app.plots
    wait_for(lambda: len(plots.handles) >= 2, what="plots shown")
    assert all(h.aspect == pytest.approx(2.2) for h in plots.handles.values())
    expand_folder(page, "Plots", ".uplot")
    page.get_by_label("Plot height").click()
    page.get_by_role("option", name="taller", exact=True).click()
    wait_for(lambda: plots.aspect == pytest.approx(0.8), what="the taller plots chosen")
    wait_for(lambda: plots.handles and all(h.aspect == pytest.approx(0.8) for h in list(plots.handles.values())),
             what="every plot taller")

    def drawn_taller() -> bool:  # in the page, once it has drawn the plots anew (they are hidden while it does)
        box = page.locator(".uplot").first.bounding_box()
        return box is not None and box["height"] > 0.9 * box["width"]

    wait_for(drawn_taller, what="the plots drawn taller than wide in the page")
    page.get_by_label("Plot height").click()
    page.get_by_role("option", name="compact", exact=True).click()
    wait_for(lambda: all(h.aspect == pytest.approx(2.2) for h in list(plots.handles.values())),
             what="compact again")
