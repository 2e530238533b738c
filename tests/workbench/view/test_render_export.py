"""Pictures of the 3-D view grabbed from the page (viser's get_render): the Screenshot button writes a PNG of the
view into the recordings folder; Record video writes the replay, frame by frame, with progress and ETA."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import expand_folder, newest_client, wait_for
from workbench.view.render import eta_text, unique_name


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
    cam = newest_client(app).camera
    view0 = np.concatenate([cam.position, cam.look_at])
    app.render_hooks.append(lambda _fr: notes.append(app.status_note))
    app.pictures.last_path = None
    try:
        page.get_by_role("button", name="Record video").click()
        wait_for(lambda: (app.pictures.last_path is not None or app.pictures.last_error is not None)
                 and not app.pictures.thread.is_alive(), timeout=120, what="video written")
    finally:
        app.render_hooks.pop()
    assert app.pictures.last_error is None
    out = app.pictures.last_path
    assert out.parent == folder and out.suffix == ".mp4"  # imageio-ffmpeg is a dependency: an MP4, not a GIF
    assert any("ETA" in n for n in notes) and app.status_note == ""
    import imageio.v3 as iio

    video = iio.imread(out, plugin="FFMPEG")  # read back: every frame, in colour, the even size encoders want
    assert video.shape[0] == 8 and video.shape[-1] == 3 and video.shape[1] % 2 == 0 and video.shape[2] % 2 == 0
    first, last = (video[i].astype(float).mean(axis=-1) for i in (0, 7))
    assert np.mean(np.abs(first - last) > 30) > 0.002  # the rod moved between the first and the last frame
    assert app.wb.replay.index == 0  # back where it was
    # the video looked at the whole episode; the page's own view is back
    # (1 mm: the page's orbit controls may settle a camera set from the server by a hair)
    wait_for(lambda: np.allclose(np.concatenate([cam.position, cam.look_at]), view0, atol=1e-3),
             what="the page's camera back where it was")


def _umask() -> int:
    from sim.support.atomicio import default_mode

    return 0o666 & ~default_mode()


def test_a_page_closed_during_its_video_ends_the_video_with_a_note(tmp_path):
    """The page that asked for a video (or a screenshot) goes away while its frames are grabbed: the video thread
    ends, says so and leaves no file (no exception escapes the thread); the screenshot is not taken, and says so."""
    import contextlib
    from types import SimpleNamespace

    from tests.workbench.conftest import make_app

    def gone(*_a, **_k):
        raise RuntimeError("Render request failed: the client disconnected before returning a frame.")

    camera = SimpleNamespace(position=(1.0, -1.0, 1.0), look_at=(0.0, 0.0, 0.5), image_width=64, image_height=48,
                             get_render=gone)
    client = SimpleNamespace(client_id=-1, camera=camera, atomic=contextlib.nullcontext)  # no longer connected
    app = make_app(wait_for_browser=False, recordings_dir=tmp_path / "rec", scenes_dir=tmp_path / "scenes")
    try:
        _write(app.files.recordings / "swing.rrd")
        app.replay.open("swing.rrd")
        thread = app.pictures.start_video(client)
        thread.join(120)
        assert not thread.is_alive()
        assert "has closed" in app.pictures.msg.content and app.pictures.last_error.startswith("the page closed")
        assert sorted(p.suffix for p in app.files.recordings.iterdir()) == [".rrd"]  # no video, no temporary
        # a screenshot asked for by a page that closed before its frame came back: said, no file, nothing raised
        app.pictures.msg.content = ""
        assert app.pictures.take_screenshot(client) is None
        assert "screenshot not taken" in app.pictures.msg.content and "has closed" in app.pictures.msg.content
        assert sorted(p.suffix for p in app.files.recordings.iterdir()) == [".rrd"]
    finally:
        app.stop()
