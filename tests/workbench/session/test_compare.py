"""Compare: a second recorded episode drawn as a translucent ghost, stepping with the shown episode's timeline
(and with the live session's time); in headless Chromium the ghost is drawn in its colour where its rod is."""
from __future__ import annotations

import io

import numpy as np
import pytest

from tools.browser import canvas_png, expand_folder, newest_client, project, slider_thumb, wait_for
from workbench.session.compare import GHOST_OPACITY, Ghost


def _write(path, lean: float, frames: int = 10, dt: float = 0.05):
    """A rod leaning towards ``lean``·x more every frame."""
    from policies.recording import Recorder
    from policies.recording.schema import StaticScene

    rec = Recorder(path)
    rec.begin_episode({"task": "synthetic", "policy": "none"}, StaticScene(rod_radius=0.04))
    s = np.linspace(0.0, 1.0, 11)
    for k in range(frames):
        x = np.stack([lean * (k + 1) / frames * s * s, np.zeros_like(s), s], 1)
        rec.log_step(control_step=k, sim_time=dt * k, node_pos=x, scalars={"tip_error": 0.1})
    rec.end_episode()
    rec.close()


def test_ghost_frame_follows_time(tmp_path):
    from workbench.session.replay import read_episodes

    _write(tmp_path / "g.rrd", 0.5, frames=5, dt=0.1)
    g = Ghost(read_episodes(tmp_path / "g.rrd")[0])
    assert [g.index_at(t) for t in (-1.0, 0.0, 0.15, 0.2, 0.4, 9.0)] == [0, 0, 1, 2, 4, 4]


@pytest.mark.browser
def test_browser_ghost_over_replay_steps_together(wb_page):
    from PIL import Image

    app, page = wb_page
    folder = app.recordings_dir
    _write(folder / "main.rrd", 0.6)
    _write(folder / "other.rrd", -0.6)
    app.replay.refresh_list()
    app.replay.open("main.rrd")
    expand_folder(page, "Recordings", "Show ghost")
    app.compare.file.value = "other.rrd"
    page.get_by_role("button", name="Show ghost").click()
    try:
        wait_for(lambda: app.compare.view is not None, timeout=30, what="ghost shown")
        v = app.compare.view
        assert v.rod.opacity == pytest.approx(GHOST_OPACITY)  # translucent
        assert v.g.index == 0
        # the timeline moves both: the ghost shows its own last frame with the main episode's last frame
        expand_folder(page, "Recordings", "Open recording")
        th = slider_thumb(page, "Timeline")
        th.focus()
        th.press("End")
        wait_for(lambda: v.g.index == 9, timeout=20, what="ghost at the timeline's end")
        np.testing.assert_allclose(v.rod.batched_positions[-1], 0.5 * sum(v.g.positions(9)[-2:]), atol=1e-6)
        # drawn in the page: ghost-blue pixels where its rod's tip is (it leans to -x, the main rod to +x)
        cam = newest_client(app).camera
        look = np.array([0.0, 0.0, 0.6])
        cam.position, cam.look_at = tuple(look + [0.0, -2.0, 0.0]), tuple(look)
        wait_for(lambda: np.allclose(cam.position, look + [0.0, -2.0, 0.0], atol=1e-3), what="camera moved")
        box = page.locator("canvas").first.bounding_box()
        uv = project(cam, v.g.positions(9)[-3:-2], box["width"], box["height"])[0]

        def ghost_pixels() -> int:
            a = np.asarray(Image.open(io.BytesIO(canvas_png(page))).convert("RGB"), dtype=int)
            u, w = int(uv[0]), int(uv[1])
            p = a[w - 6:w + 7, u - 6:u + 7]
            return int(((p[..., 2] - p[..., 0] > 25) & (p[..., 2] > 150)).sum())

        wait_for(lambda: ghost_pixels() > 5, timeout=30, what="ghost drawn where its rod is")
    finally:
        app.compare.hide()
    assert app.compare.view is None and not app.render_hooks


@pytest.mark.browser
def test_ghost_follows_live_time(wb_page):
    app, _page = wb_page
    from workbench.session.replay import read_episodes

    _write(app.recordings_dir / "live.rrd", 0.3, frames=200, dt=0.01)
    g = app.compare.show(read_episodes(app.recordings_dir / "live.rrd")[0], label="live.rrd")
    try:
        wait_for(lambda: app.wb.frame_index > 20 and app.view.last_frame.time > 0.1, timeout=30, what="live steps")
        wait_for(lambda: abs(g.t[g.index] - app.view.last_frame.time) < 0.05, timeout=10,
                 what="ghost at the live session's time")
    finally:
        app.compare.hide()


@pytest.mark.browser
def test_policy_ghost_on_the_same_scene(wb_page):
    app, page = wb_page
    wb = app.wb
    app.policy.start_task("follow_target", "zero")
    wait_for(lambda: wb.frame_index > 30, timeout=60, what="live episode running")
    expand_folder(page, "Recordings", "Ghost of a policy")
    app.compare.policy.value = "random"
    page.get_by_role("button", name="Ghost of a policy").click()
    try:
        wait_for(lambda: app.compare.view is not None, timeout=60, what="policy ghost shown")
        g = app.compare.view.g
        assert wb.policy.name == "zero" and g.ep.meta["policy"] == "random"
        wait_for(lambda: wb.frame_index > 20, timeout=30, what="live episode restarted and running")
        with wb.lock:
            wb.set_playing(False)
        wait_for(lambda: abs(g.t[g.index] - app.view.last_frame.time) < 1e-9, timeout=10, what="ghost at live time")
        with wb.lock:  # the live state itself (the last drawn frame may be a step behind the task's target)
            fr = wb.live.frame()
            t_live, target_live, x_live = fr.time, wb.policy.targets()[0], fr.node_pos
        i = g.index_at(t_live)
        np.testing.assert_allclose(g.target(i), target_live, atol=1e-9)  # the same scene (target path)
        assert np.abs(g.positions(i) - x_live).max() > 1e-3  # another policy: another motion
    finally:
        app.compare.hide()
        wb.set_playing(True)
