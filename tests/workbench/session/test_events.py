"""Events on the timeline (workbench.session.events): each kind found at its frame from synthetic series, the live history
and a recorded episode with a contact, a pull and a forced failure agreeing frame by frame, and the page's
Previous / Next event moving the cursor."""
from __future__ import annotations

import numpy as np

from workbench.session import events as ev
from workbench.session.core import Workbench
from workbench.session.obstacles import ObstacleEdit
from workbench.session.replay import ReplaySession


def kinds_at(events) -> dict[int, set[str]]:
    out: dict[int, set[str]] = {}
    for e in events:
        out.setdefault(e.frame, set()).add(e.kind)
    return out


def test_each_kind_at_its_frame():
    n = 100
    reward = np.full(n, -0.1) + 1e-3 * np.sin(np.arange(n))
    reward[30] = -5.0
    contact = np.zeros(n)
    contact[10:20] = 2
    contact[25:27] = 1
    converged = np.ones(n)
    converged[40:43] = 0
    failed = np.zeros(n)
    failed[50] = 1
    pull = np.zeros(n)
    pull[60:66] = 12.0
    hand = np.zeros(n)
    hand[70:81] = 1
    got = kinds_at(ev.detect(n, episode_starts=(0,), episode_ends=(n - 1,), reward=reward, contact_count=contact,
                             converged=converged, failed=failed, pull=pull, hand=hand, first_frame=5))
    want = {5: {"episode start"}, 15: {"first contact"}, 30: {"first contact"}, 35: {"reward spike"},
            45: {"unconverged"}, 55: {"failed step"}, 65: {"pull"}, 71: {"released"}, 75: {"take-over"},
            86: {"hand back"}, 104: {"episode end"}}
    assert got == want
    texts = {e.frame: e.text for e in ev.detect(n, converged=converged, contact_count=contact, pull=pull)}
    assert texts[40] == "unconverged (3 steps)" and texts[25] == "contact again" and texts[60] == "pull (12 N)"


def test_live_episodes_split_where_the_task_counter_starts_again():
    frames = [{"episode_step": float(k % 4), "reward": 0.0} for k in range(10)]
    got = kinds_at(ev.live_events(frames, first_frame=100))
    assert got[100] == {"episode start"} and got[103] == {"episode end"} and got[104] == {"episode start"}
    assert got[107] == {"episode end"} and got[108] == {"episode start"}


def test_neighbour_and_marks():
    es = [ev.Event(f, "pull", "p") for f in (3, 10, 10, 40)]
    assert ev.neighbour_event(es, 10, +1).frame == 40 and ev.neighbour_event(es, 10, -1).frame == 3
    assert ev.neighbour_event(es, 40, +1) is None and ev.neighbour_event(es, 3, -1) is None
    assert ev.event_marks(es) == (3, 10, 40)
    many = [ev.Event(f, "pull", "p") for f in range(100)]
    m = ev.event_marks(many, limit=5)
    assert len(m) == 5 and m[0] == 0 and m[-1] == 99


def test_a_recorded_session_shows_the_live_events_at_the_same_frames(tmp_path):
    """A live session with a contact (the rod pulled onto a sphere), a pull and a forced failure, recorded: the events
    of the recording and of the live history are the same, each at the frame where it happened."""
    wb = Workbench.builtin()
    wb.add_obstacle(ObstacleEdit("sphere", position=np.array([0.3, 0.0, 0.75]), radius=0.1))
    wb.start_recording(tmp_path / "ep.rrd")
    first = wb.frame_index + 1  # the first recorded frame is the one after this step
    for _ in range(5):
        wb.step()
    wb.grab(wb.live.state.node_pos[0, 15])
    wb.move_hand(wb.live.state.node_pos[0, 15] + [0.6, 0.0, 0.0])
    pulled = wb.frame_index + 1
    contact_at = None
    for _ in range(60):
        wb.step()
        if contact_at is None and wb._last_scalars["contact_count"] > 0:
            contact_at = wb.frame_index
    assert contact_at is not None, "the pull did not bring the rod onto the sphere"
    wb.release()
    released = wb.frame_index + 1
    wb.step()
    wb.live.state.dof[0, 8, 0] = np.nan  # a state the simulator refuses: the env fails and restarts at rest
    wb.step()
    failed = wb.frame_index
    for _ in range(3):
        wb.step()
    path = wb.stop_recording()
    live = {e for e in ev.live_events(wb.history.scalars(), first_frame=wb.history.first_index)
            if e.frame >= first and e.kind not in ("episode start", "episode end")}
    at = kinds_at(live)
    assert "pull" in at[pulled] and "first contact" in at[contact_at] and "released" in at[released]
    assert "failed step" in at[failed]
    rs = ReplaySession.open(path)
    rec = {e for e in ev.episode_events(rs.ep) if e.kind not in ("episode start", "episode end", "reward spike")}
    # the recording's frame k is the live session's frame first + k
    assert {ev.Event(e.frame + first, e.kind, e.text) for e in rec} == {e for e in live if e.kind != "reward spike"}
    ends = kinds_at(ev.episode_events(rs.ep))
    assert "episode start" in ends[0] and "episode end" in ends[len(rs.ep.positions) - 1]


def test_a_recording_carries_its_events_as_text(tmp_path):
    """The recorder writes the episode's events at ``events`` (the rerun viewer lists them); read back, they are the
    events found from the recorded scalars, at the same frames."""
    wb = Workbench.builtin()
    wb.start_recording(tmp_path / "ep.rrd")
    for _ in range(3):
        wb.step()
    wb.grab(wb.live.state.node_pos[0, 15])
    wb.move_hand(wb.live.state.node_pos[0, 15] + [0.3, 0.0, 0.0])
    for _ in range(5):
        wb.step()
    wb.release()
    for _ in range(3):
        wb.step()
    rs = ReplaySession.open(wb.stop_recording())
    found = ev.episode_events(rs.ep)
    assert {"pull", "released"} <= {e.kind for e in found}
    assert rs.ep.events == sorted((e.frame, e.text) for e in found)
