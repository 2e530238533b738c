"""Recording the live session (policies.recording.Recorder) and replaying it (ReplaySession)."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.session.core import Workbench
from workbench.session.replay import ReplaySession


def record_session(tmp_path, n=30):
    wb = Workbench.builtin()
    path = wb.start_recording(tmp_path / "session.rrd")
    tips = []
    wb.set_teleop_value(2, 0, 1.2)
    for _ in range(n):
        wb.step()
        tips.append(wb.tip.copy())
    out = wb.stop_recording()
    assert out is not None and out.exists() and out == path
    return wb, out, np.array(tips)


def test_recorded_session_replays_the_same_rod(tmp_path):
    wb, path, tips = record_session(tmp_path)
    s = ReplaySession.open(path)
    assert len(s.episodes) == 1 and s.length == len(tips)
    s.seek(len(tips) - 1)
    np.testing.assert_allclose(s.frame().tip, tips[-1], atol=1e-6)  # float32 storage
    s.seek(3)
    np.testing.assert_allclose(s.frame().tip, tips[3], atol=1e-6)
    assert s.frame().rod_radius == pytest.approx(wb.live.rod_radius)
    # the recorded newton iterations come back as a plot series
    t, v = s.series("solver/newton_iters")
    assert len(t) == len(tips) and np.all(v >= 1)
    # the commanded natural curvature is recorded (the curvature plot shows it against the actual)
    kb = np.asarray(s.ep.kappa_bar[-1], np.float64)
    np.testing.assert_allclose(kb, wb.live.ctrl.kappa_bar[0], atol=1e-6)
    assert np.abs(kb).max() > 0.0


def test_rewind_while_recording_starts_a_new_episode(tmp_path):
    wb = Workbench.builtin()
    wb.start_recording(tmp_path / "rw.rrd")
    for _ in range(10):
        wb.step()
    wb.rewind(4)
    for _ in range(3):
        wb.step()
    path = wb.stop_recording()
    s = ReplaySession.open(path)
    assert [e.steps for e in s.episodes] == [10, 3]
    s.select(1)
    assert s.frame().time == pytest.approx(5 * wb.live.dt)


def test_replay_timeline_play_and_stop_at_end(tmp_path):
    _wb, path, tips = record_session(tmp_path, n=8)
    s = ReplaySession.open(path)
    assert s.advance() is False  # paused
    s.playing = True
    frames = [s.index]
    while s.advance():
        frames.append(s.index)
    assert frames == list(range(8)) and s.playing is False


def test_unreadable_recording_is_a_clear_error(tmp_path):
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"not a recording")
    with pytest.raises(Exception, match="bad.rrd"):
        ReplaySession.open(bad)


def test_recordings_tab_exports_the_open_episode_into_the_recordings_folder(tmp_path):
    """The Recordings tab's Export HTML / Export PNG buttons write the open episode (player page) and the
    current frame (picture) into the recordings folder, named after the recording and episode."""
    import shutil
    from pathlib import Path

    from policies.recording.export import unpack_html
    from tests.workbench.conftest import make_app

    rec = tmp_path / "rec"
    rec.mkdir()
    src = Path(__file__).resolve().parents[3] / "recordings" / "examples" / "ik4d.rrd"
    shutil.copy(src, rec / "ik.rrd")
    app = make_app(recordings_dir=rec)
    try:
        panel = app.replay
        assert panel.export(png=False) is None and "open a recording first" in panel.msg.content
        panel.file.value = "ik.rrd"
        assert panel.open_listed() is not None
        app.wb.replay.seek(3)
        html = panel.export(png=False)
        png = panel.export(png=True)
        assert html == rec / "ik_ep0.html" and png == rec / "ik_ep0_f3.png"
        assert "exported ik_ep0_f3.png" in panel.msg.content
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        np.testing.assert_array_equal(unpack_html(html.read_text())["positions"], app.wb.replay.ep.positions)
    finally:
        app.stop()


def test_a_replay_that_plays_to_its_end_unticks_the_play_box(tmp_path):
    """The session draws nothing once a replay stops at its last frame, so the stop itself asks for a redraw: the
    Recordings tab's Play box and the Run tab's Playing box show the replay stopped (no page needed)."""
    from tests.workbench.conftest import make_app
    from tools.browser import wait_for

    _wb, path, _tips = record_session(tmp_path, n=8)
    app = make_app(wait_for_browser=False, recordings_dir=path.parent, scenes_dir=tmp_path / "scenes")
    try:
        wait_for(lambda: not app.compiling, what="the kernels loaded")
        rs = app.replay.open(path.name)
        rs.speed = 0.2  # a frame every 0.25 s: each drawn frame refreshes the readouts, none is left for later
        app.replay.play.value = True  # as the page's tick: its callback plays the replay
        wait_for(lambda: rs.index == rs.length - 1 and not rs.playing, what="the replay at its end")
        wait_for(lambda: app.replay.play.value is False, what="the Play box unticked at the end")
    finally:
        app.stop()


def test_the_page_callbacks_leave_the_plots_to_the_stepping_thread(tmp_path):
    """The replay's timeline and the plot height, set from another thread as the page's callbacks set them, only ask
    for a redraw: every plot is drawn by the stepping thread (viser lets one thread at a time enter the Plots tab, and
    the plot handles are shared), and the plots follow both: the cursor at the last frame, every plot as tall as
    chosen."""
    import threading

    from tests.workbench.conftest import make_app
    from tools.browser import wait_for
    from workbench.panels.plots import PLOT_ASPECTS

    _wb, path, _tips = record_session(tmp_path, n=12)
    app = make_app(wait_for_browser=False, recordings_dir=path.parent, scenes_dir=tmp_path / "scenes")
    try:
        wait_for(lambda: not app.compiling, what="the kernels loaded")
        drawn_by: set[str] = set()
        show = app.plots.show

        def spy(plots):
            drawn_by.add(threading.current_thread().name)
            show(plots)

        app.plots.show = spy
        rs = app.replay.open(path.name)
        t_last = float(rs.ep.sim_time[-1])

        def page():
            for k in range(rs.length):
                app.replay.timeline.value = k
            app.plots.height.value = "taller"

        callbacks = threading.Thread(target=page, name="page-callbacks")
        callbacks.start()
        callbacks.join()

        def at_last_frame() -> bool:
            lines = [(p.data[0], p.data[list(p.labels).index("timeline")]) for p in app.plots.shown
                     if "timeline" in p.labels]
            return bool(lines) and all(np.all(x[np.isfinite(line)] == t_last) for x, line in lines)

        wait_for(at_last_frame, what="the plots' cursor at the replay's last frame")
        wait_for(lambda: app.plots.handles and all(h.aspect == PLOT_ASPECTS["taller"]
                                                   for h in app.plots.handles.values()), what="the taller plots")
        assert drawn_by == {"rodlab-sim"}, drawn_by  # workbench.session.runner.SimThread's
    finally:
        app.stop()
