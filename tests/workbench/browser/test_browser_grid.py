"""Real browser: the Grid of envs runs N envs of a task under a policy, each in its own cell (N rods drawn in the
page, each with its own target, every env's clamp glyphs in one batched node per kind, hidden by the Display tab's
"Fixes and loads"), and a click on one rod focuses that env (colour, camera, readouts)."""
from __future__ import annotations

import io
import re

import numpy as np
import pytest

from tools.browser import WAIT_MS, canvas_png, expand_folder, newest_client, project, retry_until, wait_for
from workbench.session.grid import GridSession, cell_offsets

pytestmark = pytest.mark.browser


def test_cell_offsets_do_not_overlap():
    off = cell_offsets(16, 2.0)
    d = np.linalg.norm(off[:, None] - off[None], axis=-1) + np.eye(16) * 1e9
    assert off.shape == (16, 3) and d.min() == pytest.approx(2.0)
    with pytest.raises(ValueError, match="number of envs"):
        GridSession("follow_target", "zero", 0)


def _rgb(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)


def _near(img: np.ndarray, uv, pred, r: int = 5) -> bool:
    u, v = int(round(uv[0])), int(round(uv[1]))
    patch = img[max(v - r, 0):v + r + 1, max(u - r, 0):u + r + 1]
    return bool(pred(patch).any())


#: the page's scene nodes under /grid/boundary: name -> visibility set by the server
GLYPHS_JS = """() => Object.fromEntries(Object.entries(window.__viserSceneTree?.getState() ?? {})
    .filter(([name, node]) => name.startsWith('/grid/boundary/') && node && node.message)
    .map(([name, node]) => [name, node.visibility !== false]))"""


def _orange(p):
    return (p[..., 0] > 120) & (p[..., 0] - p[..., 2] > 70)


def _blue(p):
    return (p[..., 2] > 120) & (p[..., 2] - p[..., 0] > 70)


def test_grid_shows_n_rods_and_click_focuses(wb_page):
    app, page = wb_page
    n = 4
    expand_folder(page, "Policy", "Run grid")
    app.policy.task.value = "follow_target"
    app.grid.envs.value = n
    page.get_by_role("button", name="Run grid").click()
    try:
        wait_for(lambda: app.grid.runner is not None and app.grid.runner.frames >= 3, timeout=120, what="grid running")
        s, view = app.grid.session, app.grid.view
        assert s.n == n and s.positions().shape == (n, s.n_nodes, 3)
        tg = s.targets()
        assert tg is not None and len({tuple(np.round(t - o, 6)) for t, o in zip(tg, s.offsets)}) == n  # own targets
        cam = newest_client(app).camera
        want_pos, want_look = view.cell_camera(None)
        wait_for(lambda: np.allclose(cam.look_at, want_look, atol=1e-3), what="camera on the whole grid")
        box = page.locator("canvas").first.bounding_box()
        with app.grid.runner.lock:  # hold the envs still while the page is read
            view.render()
            mid = s.positions()[:, s.n_nodes // 2]
            uv = project(cam, mid, box["width"], box["height"])
            img = _rgb(canvas_png(page))
            wait_for(lambda: all(_near(_rgb(canvas_png(page)), uv[e], _blue if e == 0 else _orange)
                                 for e in range(n)), timeout=30, what="every env's rod drawn in its cell")
        # click env 3's rod: it is focused (blue), the camera moves to its cell, its readouts show
        k = n - 1
        def click_env() -> None:
            with app.grid.runner.lock:
                uvk = project(cam, s.positions()[k, s.n_nodes // 2][None], box["width"], box["height"])[0]
                page.mouse.click(uvk[0] + box["x"], uvk[1] + box["y"])

        # a software-GL page may not have drawn the last frame at the first click
        retry_until(click_env, lambda: view.focus == k, what="click focuses env 3")
        assert view.focus == k and int(app.grid.focus.value) == k
        wait_for(lambda: np.allclose(cam.look_at, view.cell_camera(k)[1], atol=1e-3), what="camera on env 3")
        wait_for(lambda: f"env {k} ·" in app.grid.msg.content, what="env 3's readouts")
        assert img.std() > 5
        # the arm's clamp in every cell: one batched node per kind of glyph, n instances each
        glyphs = ("/grid/boundary/fixed_nodes", "/grid/boundary/twist_edges")
        wait_for(lambda: page.evaluate(GLYPHS_JS) == dict.fromkeys(glyphs, True), what="the grid's glyphs shown")
        assert len(view.boundary.fixed.batched_positions) == n * len(view.boundary.b.fixed_nodes)
        page.get_by_text("Display", exact=True).first.click()  # (not expand_folder: "Stop grid" matches "top")
        box = page.get_by_label("Fixes and loads")
        box.wait_for(state="visible", timeout=WAIT_MS)
        box.click()
        try:
            wait_for(lambda: page.evaluate(GLYPHS_JS) == dict.fromkeys(glyphs, False), what="the grid's glyphs hidden")
        finally:
            box.click()
        wait_for(lambda: page.evaluate(GLYPHS_JS) == dict.fromkeys(glyphs, True), what="the grid's glyphs shown again")
    finally:
        app.grid.stop()
    assert app.grid.session is None


def _start_grid(app, page, n: int) -> None:
    expand_folder(page, "Policy", "Run grid")
    app.policy.task.value = "follow_target"
    app.grid.envs.value = n
    page.get_by_role("button", name="Run grid").click()
    wait_for(lambda: app.grid.runner is not None and app.grid.runner.frames >= 3, timeout=120, what="grid running")


def _page_text(page) -> str:
    return page.evaluate("() => document.body.innerText")


def _shown_steps(page) -> tuple[int, int]:
    """(control step in the grid's readout, control step in the status line) as the page shows them (-1: none)."""
    text = _page_text(page)
    readout = [int(v) for v in re.findall(r"control step (\d+)\s*\n\s*env \d+ ·", text)]
    status = [int(v) for v in re.findall(r"grid · follow_target · .*?control step (\d+) · t =", text)]
    return max(readout, default=-1), max(status, default=-1)


def test_grid_readouts_follow_the_running_grid(wb_page):
    """The live session is paused while the grid runs, so nothing of it refreshes the readouts: the grid's runner
    does (its readout and the status line follow the envs' control steps, without touching Focus env)."""
    app, page = wb_page
    _start_grid(app, page, 9)
    try:
        s = app.grid.session
        for k in (20, 40):  # the page's readouts keep following the envs, not only once
            wait_for(lambda k=k: s.steps >= k, timeout=120, what=f"{k} control steps of the grid")
            wait_for(lambda k=k: min(_shown_steps(page)) >= k, what=f"readout and status at control step >= {k}")
        assert int(app.grid.focus.value) == 0
        assert "9 envs" in app.controls.status.content and "live session is paused" in app.controls.status.content
    finally:
        app.grid.stop()


#: visibility of the live scene's parents in the page (hidden while a grid is drawn in its place)
LIVE_JS = """() => Object.fromEntries(['/rod', '/boundary', '/contacts', '/obstacles', '/target'].map((name) => {
    const node = window.__viserSceneTree?.getState()?.[name];
    return [name, node && node.message ? node.visibility !== false : null]; }))"""


def test_stop_grid_goes_back_to_the_live_scene(wb_page):
    """While the grid runs the live scene (rod, obstacles, glyphs) is hidden and the cells sit on the floor grid;
    Stop grid shows the live scene again and puts the camera back where it was before the grid."""
    from workbench.session.obstacles import default_edit

    app, page = wb_page
    app.wb.add_obstacle(default_edit("sphere", position=(0.5, -0.4, 0.6)))
    wait_for(lambda: len(app.view.obstacle_nodes) == 1, what="the live obstacle drawn")
    cam = newest_client(app).camera
    app.view.set_camera("front")
    before = np.asarray(app.view.camera[1]), np.asarray(app.view.camera[2])
    wait_for(lambda: np.allclose(cam.position, before[0], atol=1e-3) and np.allclose(cam.look_at, before[1], atol=1e-3),
             what="camera on the live scene")
    wait_for(lambda: page.evaluate(LIVE_JS)["/rod"] is True, what="the live rod shown")
    _start_grid(app, page, 9)
    try:
        s = app.grid.session
        wait_for(lambda: not any(page.evaluate(LIVE_JS).values()), what="the live scene hidden in the page")
        half = 0.5 * app.view.ground.width  # every cell's rod base on the floor grid
        assert np.abs(s.offsets[:, :2]).max() < half
        wait_for(lambda: not np.allclose(cam.look_at, before[1], atol=1e-3), what="camera on the grid")
    finally:
        page.get_by_role("button", name="Stop grid").click()
    wait_for(lambda: app.grid.session is None, what="grid stopped")
    wait_for(lambda: np.allclose(cam.position, before[0], atol=1e-3) and np.allclose(cam.look_at, before[1], atol=1e-3),
             what="camera back on the live scene")
    shown = {"/rod": True, "/boundary": True, "/contacts": True, "/obstacles": True, "/target": False}  # teleop: no target
    wait_for(lambda: page.evaluate(LIVE_JS) == shown, what="the live scene shown again")


def test_dragging_an_envs_rod_pulls_that_env(wb_page):
    """In the grid, a drag on one env's rod pulls that env (the hand drawn while held); release lets go."""
    app, page = wb_page
    _start_grid(app, page, 4)
    try:
        s, view = app.grid.session, app.grid.view
        k = 1
        cam = newest_client(app).camera
        box = page.locator("canvas").first.bounding_box()
        corner = np.array([box["x"], box["y"]])
        held = {"down": False}

        def press_and_drag() -> None:
            if held["down"]:
                page.mouse.up()
            with app.grid.runner.lock:
                a = s.positions()[k, s.n_nodes - 3]
            uv = project(cam, np.stack([a, a + [0.3, 0.0, 0.0]]), box["width"], box["height"]) + corner
            page.mouse.move(*uv[0])
            page.mouse.down()
            held["down"] = True
            page.mouse.move(*uv[1], steps=10)
            page.mouse.move(uv[1][0], uv[1][1] + 1.0)

        retry_until(press_and_drag, lambda: s.pull is not None, what=f"env {k}'s rod grabbed")
        assert s.pull_env == k
        wait_for(lambda: view.hand_line.visible, what="the hand drawn in the grid")
        wait_for(lambda: s.core.ctrl.force is not None and np.abs(s.core.ctrl.force[k]).max() > 0,
                 what="a force on that env")
        assert not np.delete(s.core.ctrl.force, k, axis=0).any()  # on that env only
        page.mouse.up()
        held["down"] = False
        wait_for(lambda: s.pull is None and not view.hand_line.visible, what="let go")
    finally:
        app.grid.stop()
