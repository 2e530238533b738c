"""Pictures of the 3-D view grabbed from the page (viser's get_render): the Screenshot button writes a PNG of the
view into the recordings folder; Record video writes the replay, frame by frame, with progress and ETA."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import expand_folder, wait_for
from workbench.render_export import eta_text, unique_name


def test_eta_and_names(tmp_path):
    assert eta_text(0, 10, 0.0) == "frame 0 / 10"
    assert eta_text(5, 10, 2.5) == "frame 5 / 10 · ETA 2 s"  # 0.5 s per frame, 5 left -> 2.5 s
    (tmp_path / "a.png").write_bytes(b"")
    assert unique_name(tmp_path, "a", ".png").name == "a_2.png"


def _write(path, frames: int = 8):
    from policies.recording import Recorder
    from policies.recording.schema import StaticScene

    rec = Recorder(path)
    rec.begin_episode({"task": "synthetic", "policy": "none"}, StaticScene(rod_radius=0.03))
    s = np.linspace(0.0, 1.0, 11)
    for k in range(frames):  # a rod swinging from +x to -x
        x = np.stack([(0.6 - 0.17 * k) * s * s, np.zeros_like(s), s], 1)
        rec.log_step(control_step=k, sim_time=0.05 * k, node_pos=x, scalars={"tip_error": 0.1})
    rec.end_episode()
    rec.close()


@pytest.mark.browser
def test_browser_screenshot_and_video(wb_page):
    from PIL import Image

    app, page = wb_page
    folder = app.files.recordings
    app.pictures.last_path = None
    expand_folder(page, "Recordings", "Screenshot")
    page.get_by_role("button", name="Screenshot").click()
    wait_for(lambda: app.pictures.last_path is not None, timeout=30, what="screenshot file")
    png = app.pictures.last_path
    assert png.parent == folder and png.suffix == ".png" and not list(folder.glob(".*"))  # no temporary left
    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[0] > 100 and img.shape[1] > 100
    assert img.std() > 5  # a picture of the scene, not a blank image
    assert oct(png.stat().st_mode & 0o777) == oct(0o666 & ~_umask())
    # video of a replay: every frame differs (the rod swings), progress in the status line meanwhile
    _write(folder / "swing.rrd")
    app.replay.open("swing.rrd")
    wait_for(lambda: app.wb.mode == "replay", what="replay open")
    notes = []
    app.render_hooks.append(lambda _fr: notes.append(app.status_note))
    try:
        page.get_by_role("button", name="Record video").click()
        wait_for(lambda: app.pictures.thread is not None and not app.pictures.thread.is_alive(), timeout=120,
                 what="video written")
    finally:
        app.render_hooks.pop()
    assert app.pictures.last_error is None
    out = app.pictures.last_path
    assert out.parent == folder and out.suffix in (".gif", ".mp4")
    assert any("ETA" in n for n in notes) and app.status_note == ""
    if out.suffix == ".gif":
        gif = Image.open(out)
        assert gif.n_frames == 8
        frames = []
        for i in (0, 7):
            gif.seek(i)
            frames.append(np.asarray(gif.convert("L"), dtype=float))
        assert np.mean(np.abs(frames[0] - frames[1]) > 30) > 0.002  # the rod moved between first and last frame
    assert app.wb.replay.index == 0  # back where it was


def _umask() -> int:
    from sim.support.atomicio import default_mode

    return 0o666 & ~default_mode()
