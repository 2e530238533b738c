"""Real browser: what the page shows matches the server's state (no drift between the two).

``--task T`` shows T in the Task/Policy dropdowns (and "Run policy" then runs T), the reward text is cleared
by "Stop policy", the status line shows the replayed frame during a replay, the Play checkbox is unticked by
"Close recording", and a fresh session stays paused at frame 0 until the first browser connects.
"""
from __future__ import annotations

import pytest
from playwright.sync_api import expect

from tools.browser import expand_folder, open_page, slider_thumb, wait_for

pytestmark = pytest.mark.browser


@pytest.fixture
def task_app(tmp_path):
    """A workbench started as ``rodlab workbench --task ik4d`` would start it (no page yet)."""
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    app = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, recordings_dir=tmp_path / "rec",
                       scenes_dir=tmp_path / "scenes")
    try:
        app.policy.start_task("ik4d")  # what workbench_main does for --task, before start()
        app.start()
        yield app
    finally:
        app.stop()


def test_task_option_shown_in_page_and_paused_until_browser(browser, task_app):
    app, wb = task_app, task_app.wb
    # nothing connected yet: paused at frame 0 (the sim thread runs but does not step)
    assert app.waiting_for_browser and not wb.playing
    assert app.thread._thread.is_alive() and wb.frame_index == 0
    page = open_page(browser, app, width=960, height=640)
    try:
        wait_for(lambda: wb.playing and wb.frame_index > 2, timeout=120, what="session to start with the page")
        assert not app.waiting_for_browser
        expect(page.get_by_label("Playing")).to_be_checked()
        expand_folder(page, "Policy", "Run policy")
        expect(page.get_by_label("Task")).to_have_value("ik4d")
        expect(page.get_by_label("Policy file")).to_have_value("ik4d.zip")
        # pressing "Run policy" restarts the task shown, it does not switch to another one
        first = wb.policy
        page.get_by_role("button", name="Run policy").click()
        wait_for(lambda: wb.policy is not first and wb.policy is not None, timeout=60, what="policy restarted")
        assert wb.policy.task == "ik4d" and wb.policy.name == "ik4d"
        wait_for(lambda: "reward" in app.policy.reward.content, timeout=60, what="reward line")
        # Stop clears the reward text (in the page too) and the status line's reward readout
        page.get_by_role("button", name="Stop policy").click()
        wait_for(lambda: wb.mode == "teleop" and app.policy.reward.content == "", what="reward text cleared")
        wait_for(lambda: "reward" not in app.controls.status.content, what="status without reward")
        expect(page.get_by_text("return", exact=False)).to_have_count(0)
    finally:
        page.close()


def test_replay_status_and_play_checkbox(wb_page):
    from workbench.session.core import Workbench

    app, page = wb_page
    wb = app.wb
    rec = Workbench.builtin()
    rec.start_recording(app.recordings_dir / "status.rrd")
    for k in range(12):
        rec.set_teleop_value(1, 0, 0.1 * k)
        rec.step()
    rec.stop_recording()
    app.replay.refresh_list()
    expand_folder(page, "Recordings", "Open recording")
    app.replay.file.value = "status.rrd"
    page.get_by_role("button", name="Open recording").click()
    wait_for(lambda: wb.mode == "replay" and wb.replay is not None, timeout=30, what="recording opened")
    # the status shows the replay's frame (the live session keeps its own frame number meanwhile)
    th = slider_thumb(page, "Timeline")
    th.focus()
    th.press("End")
    last = wb.replay.length - 1
    wait_for(lambda: wb.replay.index == last, what="timeline at the end")
    want = f"frame {last} / {last}"
    wait_for(lambda: want in app.controls.status.content, what="status with the replay frame")
    expect(page.get_by_text(want, exact=False)).to_be_visible()
    assert app.controls.status.content.startswith("**replay**")
    # play, then close while playing: the Play checkbox is unticked in the page
    th.press("Home")
    wait_for(lambda: wb.replay.index == 0, what="timeline at the start")
    page.get_by_label("Play recording").check()
    wait_for(lambda: wb.replay is not None and wb.replay.playing, what="replay playing")
    page.get_by_role("button", name="Close recording").click()
    wait_for(lambda: wb.mode == "teleop", what="replay closed")
    expect(page.get_by_label("Play recording")).not_to_be_checked()
    assert app.replay.play.value is False


def test_a_trimmed_history_is_said_in_the_page(wb_page):
    """The rewind history keeps a bounded number of frames; when it drops the oldest, the page says so."""
    from workbench.session.history import History

    app, page = wb_page
    wb = app.wb
    kept = wb.history
    try:
        with wb.lock:
            wb.history = History(capacity=20)
        wait_for(lambda: wb.history.dropped > 0, what="frames dropped from a 20-frame history")
        page.get_by_role("tab", name="Run", exact=True).click()  # the shared page may be on another tab
        expand_folder(page, "Rewind", "Rewind")
        expect(page.get_by_text("history trimmed: the oldest", exact=False)).to_be_visible()
        assert "rewind keeps the last 20" in app.policy.rewind_note.content
        with wb.lock:
            wb.history = kept
        wb.reset()  # a fresh session: nothing dropped, the note goes away
        wait_for(lambda: app.policy.rewind_note.content == "", what="the note cleared after a reset")
        expect(page.get_by_text("history trimmed: the oldest", exact=False)).to_have_count(0)
    finally:
        with wb.lock:
            wb.history = kept
