"""Events in a real browser: a recording with a contact, a pull and a forced failure opened in the page; the timeline
marks its events, "Next event" / "Previous event" (and the keys ] and [) seek to them; live, they move the Rewind
slider."""
from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import expect

from tools.browser import expand_folder, wait_for
from workbench.session import events as ev
from workbench.session.obstacles import ObstacleEdit

pytestmark = pytest.mark.browser


def _blur(page) -> None:
    page.evaluate("() => { if (document.activeElement) document.activeElement.blur(); }")


def _record(wb, path):
    """A short live session into ``path``: a pull onto a sphere, a release and a forced failure."""
    wb.set_playing(False)
    wb.add_obstacle(ObstacleEdit("sphere", position=np.array([0.3, 0.0, 0.75]), radius=0.1))
    wb.start_recording(path)
    for _ in range(3):
        wb.step()
    wb.grab(wb.live.state.node_pos[0, 15])
    wb.move_hand(wb.live.state.node_pos[0, 15] + [0.6, 0.0, 0.0])
    for _ in range(40):
        wb.step()
    wb.release()
    wb.step()
    with wb.lock:  # the stepping thread never draws the poisoned state: the step below fails and restores it
        wb.live.state.dof[0, 8, 0] = np.nan
        wb.step()
    for _ in range(3):
        wb.step()
    return wb.stop_recording()


def test_next_and_previous_event_seek_the_replay(wb_page):
    app, page = wb_page
    wb = app.wb
    path = _record(wb, app.recordings_dir / "events.rrd")
    app.replay.refresh_list()
    rs = app.replay.open(path)
    frames = sorted({e.frame for e in ev.episode_events(rs.ep)})
    kinds = {e.kind for e in ev.episode_events(rs.ep)}
    assert {"pull", "first contact", "released", "failed step"} <= kinds
    wait_for(lambda: app.replay.timeline._marks is not None
             and [m.value for m in app.replay.timeline._marks] == [float(f) for f in frames], what="timeline marks")
    expand_folder(page, "Recordings", "Open recording")
    wait_for(lambda: page.locator(".mantine-Slider-mark").count() >= len(frames), what="the marks in the page")
    expand_folder(page, "Run", "Next event")
    want = [f for f in frames if f > 0]
    for f in want[:3]:
        page.get_by_role("button", name="Next event").click()
        wait_for(lambda f=f: rs.index == f and int(app.replay.timeline.value) == f, what=f"replay at event frame {f}")
    wait_for(lambda: f"**{want[2]}:" in app.events.list.content, what="the list shows the current event")
    _blur(page)
    page.keyboard.press("[")
    wait_for(lambda: rs.index == want[1], what="[ goes to the previous event")
    page.keyboard.press("]")
    wait_for(lambda: rs.index == want[2], what="] goes to the next event")
    wb.close_replay()
    path.unlink()  # the shared page's Recording list is left as it was (later tests open what they list)
    app.replay.refresh_list()


def test_previous_event_moves_the_rewind_slider_live(wb_page):
    app, page = wb_page
    wb = app.wb
    wb.set_playing(False)
    for _ in range(3):
        wb.step()
    x = wb.live.state.node_pos[0, 15]
    wb.grab(x)
    wb.move_hand(x + [0.2, 0.0, 0.0])
    grabbed = wb.frame_index + 1
    for _ in range(10):
        wb.step()
    wb.release()
    for _ in range(3):
        wb.step()
    newest = wb.frame_index
    app.request_render()
    wait_for(lambda: int(app.policy.rewind.max) == newest, what="the rewind slider's range")
    app.policy.choose_rewind_frame(newest)
    found = ev.live_events(wb.history.scalars(), first_frame=wb.history.first_index)
    assert {"pull", "released"} <= {e.kind for e in found}
    back = sorted({e.frame for e in found if grabbed <= e.frame < newest}, reverse=True)  # release ... pull
    expand_folder(page, "Run", "Previous event")
    for f in back:
        page.get_by_role("button", name="Previous event").click()
        wait_for(lambda f=f: int(app.policy.rewind.value) == f, what=f"the rewind slider at frame {f}")
    assert back[-1] == grabbed and wb.frame_index == newest  # moving the slider does not rewind: Rewind does
    page.get_by_role("button", name="Rewind", exact=True).click()
    wait_for(lambda: wb.frame_index == grabbed, what="rewound to the pull")
    expect(page.get_by_label("Playing")).not_to_be_checked()  # the page's action is over (the box shows the pause)


def test_keys_play_pause_and_step_a_replay(wb_page):
    """In a replay, space plays and pauses the recording and → steps it one frame (paused), the Recordings tab's
    Timeline and "Play recording" box following."""
    app, page = wb_page
    wb = app.wb
    path = _record(wb, app.recordings_dir / "keys.rrd")
    app.replay.refresh_list()
    rs = app.replay.open(path)
    try:
        expand_folder(page, "Recordings", "Open recording")
        _blur(page)
        assert not rs.playing and rs.index == 0
        for n in (1, 2, 3):
            page.keyboard.press("ArrowRight")
            wait_for(lambda n=n: rs.index == n and int(app.replay.timeline.value) == n,
                     what=lambda n=n: f"→ steps the replay to frame {n} (at {rs.index}, slider "
                                      f"{app.replay.timeline.value})")
        assert not rs.playing
        expect(page.get_by_label("Play recording")).not_to_be_checked()
        rs.speed = 0.25  # seconds of wall clock for the rest of the episode, so it is still playing when paused
        page.keyboard.press("Space")
        wait_for(lambda: rs.index > 3, what="space plays the recording")
        # the box shows it (unless the episode has already ended, which stops the replay and unticks it)
        wait_for(lambda: bool(app.replay.play.value) or not rs.playing, what="the Play recording box ticked")
        page.keyboard.press("Space")
        wait_for(lambda: not rs.playing, what="space pauses it")
        expect(page.get_by_label("Play recording")).not_to_be_checked()
        at = rs.index
        wait_for(lambda: int(app.replay.timeline.value) == at, what="the timeline at the paused frame")
        if at < rs.length - 1:
            page.keyboard.press("ArrowRight")
            wait_for(lambda: rs.index == at + 1, what="→ steps on from the paused frame")
    finally:
        wb.close_replay()
        path.unlink()
        app.replay.refresh_list()
