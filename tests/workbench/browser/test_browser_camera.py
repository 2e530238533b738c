"""Real browser: "Follow tip" keeps the page's camera looking at the rod's tip (its distance and direction kept) as
the tip moves; off again, the camera stays where it is."""
from __future__ import annotations

import io

import numpy as np
import pytest

from tests.helpers.workbench import pause_drawn
from tools.browser import canvas_png, expand_folder, newest_client, wait_for

pytestmark = pytest.mark.browser


def _centre(png: bytes) -> np.ndarray:
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    h, w = img.shape[:2]
    return img[h // 2 - 2:h // 2 + 3, w // 2 - 2:w // 2 + 3].reshape(-1, 3)


def _tip(app) -> np.ndarray:
    return np.asarray(app.view.last_frame.node_pos[-1], np.float64)


def _offset_at_rest(cam) -> np.ndarray:
    """The camera's offset from its look-at point once the page has stopped reporting changes (after a preset view
    the page's camera controls may still settle and send a slightly different camera)."""
    seen: list[np.ndarray] = []

    def at_rest() -> bool:
        seen.append(np.asarray(cam.position) - np.asarray(cam.look_at))
        return len(seen) >= 3 and np.allclose(seen[-1], seen[-3], atol=1e-9)

    wait_for(at_rest, interval=0.3, what="the camera at rest")
    return seen[-1]


def test_follow_tip(wb_page):
    app, page = wb_page
    wb, view = app.wb, app.view
    view.overlays.color_by = "none"  # the rod in its plain orange
    cam = newest_client(app).camera
    expand_folder(page, "Display", "top")
    page.get_by_role("button", name="iso", exact=True).click()
    wait_for(lambda: view.overlays.follow_tip is False, what="follow off at the start")
    offset0 = _offset_at_rest(cam)
    page.get_by_label("Follow tip").click()
    wait_for(lambda: view.overlays.follow_tip, what="follow on")
    try:
        for k, value in ((2, 1.4), (3, -1.8)):  # move the tip twice
            wb.set_playing(True)
            wb.set_teleop_value(k, 0, value)
            f = wb.frame_index
            wait_for(lambda f=f: wb.frame_index > f + 40, timeout=60, what="the tip to move")
            pause_drawn(app)
            tip = _tip(app)
            # the page reports position and look-at of one camera state; read both until they are of the same one
            # (1 mm: the page's orbit controls may settle a camera set from the server by a hair)
            wait_for(lambda tip=tip: np.allclose(cam.look_at, tip, atol=1e-3)
                     and np.allclose(np.asarray(cam.position) - np.asarray(cam.look_at), offset0, atol=1e-3),
                     what=lambda tip=tip: f"look-at on the tip {tip}, at the offset {offset0}: the page's look-at is "
                                          f"{np.asarray(cam.look_at)}, its offset "
                                          f"{np.asarray(cam.position) - np.asarray(cam.look_at)}")

            def orange_centre() -> bool:  # the page really looks at the tip: the rod's end is in the middle
                p = _centre(canvas_png(page))
                return bool(np.median(p[:, 0] - p[:, 2]) > 60 and np.median(p[:, 0]) > 120)

            wait_for(orange_centre, timeout=30, interval=0.5, what="the tip in the middle of the view")
        page.get_by_label("Follow tip").click()
        wait_for(lambda: not view.overlays.follow_tip, what="follow off")
        look = np.asarray(cam.look_at).copy()
        wb.set_playing(True)
        wb.set_teleop_value(2, 0, -1.0)
        f = wb.frame_index
        wait_for(lambda: wb.frame_index > f + 40, timeout=60, what="the tip to move again")
        pause_drawn(app)
        assert np.linalg.norm(_tip(app) - look) > 0.05
        np.testing.assert_allclose(cam.look_at, look, atol=1e-3)  # the camera stayed (as the page may settle it)
    finally:
        view.overlays.follow_tip = False
        view.overlays.color_by = "curvature"
        app.controls.follow.value = False
