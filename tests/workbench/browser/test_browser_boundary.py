"""Real browser: the workbench opened on assets/scenes/strip_tip_load.toml draws its clamp (boxes on nodes 0 and 1, a
ring on edge 0) and its tip load (an arrow and a label with the force in N) in the page's scene, following the rod,
and the Display tab's "Fixes and loads" checkbox hides and shows them there."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tools.browser import expand_folder, open_page, wait_for

pytestmark = pytest.mark.browser

SCENE = Path(__file__).resolve().parents[3] / "assets" / "scenes" / "strip_tip_load.toml"
GLYPHS = ("/boundary/fixed_nodes", "/boundary/twist_edges", "/boundary/loads", "/boundary/load_label_0")

#: the page's scene nodes under /boundary: name -> (message type, visibility set by the server)
SCENE_JS = """() => Object.fromEntries(Object.entries(window.__viserSceneTree?.getState() ?? {})
    .filter(([name, node]) => name.startsWith('/boundary/') && node && node.message)
    .map(([name, node]) => [name, {type: node.message.type, visible: node.visibility !== false,
                                   text: node.message.props?.text ?? null}]))"""


@pytest.fixture
def strip_app(tmp_path):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    app = WorkbenchApp(Workbench.from_path(SCENE), port=0, env_map=False, recordings_dir=tmp_path / "rec",
                       scenes_dir=tmp_path / "scenes").start()
    try:
        yield app
    finally:
        app.stop()


def _page_glyphs(page) -> dict:
    return page.evaluate(SCENE_JS)


def test_fixes_and_loads_in_the_page(browser, strip_app):
    app, wb, view = strip_app, strip_app.wb, strip_app.view
    page = open_page(browser, app, width=960, height=640)
    try:
        wait_for(lambda: set(GLYPHS) <= set(_page_glyphs(page)), timeout=30, what="the glyphs in the page's scene")
        got = _page_glyphs(page)
        assert set(got) == set(GLYPHS)  # one node per kind of glyph, one label for the one load
        assert got["/boundary/fixed_nodes"]["type"] == got["/boundary/twist_edges"]["type"] == "BatchedMeshesMessage"
        assert got["/boundary/loads"]["type"] == "ArrowMessage"
        wait_for(lambda: all(g["visible"] for g in _page_glyphs(page).values()), what="the glyphs shown")
        wait_for(lambda: _page_glyphs(page)["/boundary/load_label_0"]["text"] == "0.01 N", what="the load's label")
        # they follow the rod: the clamp boxes on nodes 0, 1, the arrow from the bent tip straight down
        wait_for(lambda: wb.frame_index > 30, timeout=120, what="the rod to move")
        wb.set_playing(False)
        app.controls.set_quiet(app.controls.playing, False)
        app.request_render()
        with wb.lock:
            x = np.asarray(wb.live.state.node_pos[0], np.float64).copy()
        wait_for(lambda: np.allclose(view.last_frame.node_pos, x), what="the paused frame drawn")
        assert x[-1, 2] < 0.5 - 1e-4  # the tip went down under the load
        np.testing.assert_allclose(view.boundary.fixed.batched_positions, x[[0, 1]], atol=1e-6)
        pts = np.asarray(view.boundary.arrows.points, np.float64)
        np.testing.assert_allclose(pts[0, 0], x[-1], atol=1e-6)
        d = pts[0, 1] - pts[0, 0]
        np.testing.assert_allclose(d / np.linalg.norm(d), [0.0, 0.0, -1.0], atol=1e-6)
        # the Display checkbox hides them in the page, and shows them again
        expand_folder(page, "Display", "top")
        box = page.get_by_label("Fixes and loads")
        assert box.is_checked()
        box.click()
        wait_for(lambda: not view.overlays.boundary, what="overlay off")
        wait_for(lambda: not any(g["visible"] for g in _page_glyphs(page).values()), what="glyphs hidden in the page")
        assert not any(h.visible for h in view.boundary.nodes)
        box.click()
        wait_for(lambda: view.overlays.boundary, what="overlay on")
        wait_for(lambda: all(g["visible"] for g in _page_glyphs(page).values()), what="glyphs shown again")
    finally:
        page.close()
