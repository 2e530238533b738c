"""A session driven by a hostile client sending hundreds of GUI values per second (plausible ones that load
scenes, run policies and grids, open recordings, record and export; and values of the wrong kind): the
callbacks waiting to run stay bounded by the number of callbacks (not by the client's rate), every failed action
is accounted for, and the server still answers afterwards."""
from __future__ import annotations

import pytest

from tools import soak
from tools.browser import wait_for
from tools.hostile_client import HostileClient


@pytest.fixture
def app(tmp_path):
    from workbench.app import WorkbenchApp
    from workbench.core import Workbench

    a = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, wait_for_browser=False,
                     scenes_dir=tmp_path / "scenes", recordings_dir=tmp_path / "recordings").start()
    yield a
    a.stop()


def test_hostile_session_keeps_its_queues_bounded_and_answers(app):
    gui = app.server.gui
    n_callbacks = sum(len(h._impl.update_cb) for h in gui._gui_input_handle_from_uuid.values())
    most_waiting = 0

    def sample(_s) -> None:
        nonlocal most_waiting
        most_waiting = max(most_waiting, gui._thread_executor.waiting() + app.server.scene._thread_executor.waiting())

    samples = soak.drive(app, 20.0, seed=7, rate_hz=200.0, sample_s=0.5, progress=sample)
    assert len(samples) > 10 and all(rss > 0 for _t, rss, _b in samples)
    assert most_waiting <= n_callbacks + 16  # scene callbacks (clicks) come on top of the GUI's
    assert gui._thread_executor.coalesced > 0  # the client did send faster than its callbacks ran
    # refusals were counted, and the session still answers a page's value
    assert sum(app.refused_values.values()) > 0
    client = HostileClient(app)
    try:
        speed = app.controls.speed
        marker = 0.6 if speed.value != 0.6 else 0.9
        client.set(speed, marker)
        wait_for(lambda: speed.value == marker, what="a value after the soak")
    finally:
        client.close()
