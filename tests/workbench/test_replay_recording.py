"""Recording the live session (policies.recording.Recorder) and replaying it (ReplaySession)."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.core import Workbench
from workbench.replay import ReplaySession


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
