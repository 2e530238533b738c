"""Values of the wrong kind from a client never reach viser's casts or the workbench's callbacks, and a page
action that fails is said in the status line instead of a traceback in viser's thread pool."""
from __future__ import annotations

import math

import numpy as np
import pytest

from tools.browser import wait_for
from tools.hostile_client import HostileClient
from workbench.panels.guard import MAX_TEXT, value_problem


@pytest.mark.parametrize("current, value, ok", [
    (True, False, True), (True, 1, False), (True, "yes", False), (True, None, False),
    (1.0, 2, True), (1.0, 2.5, True), (1.0, True, False), (1.0, math.nan, False), (1.0, math.inf, False),
    (1.0, "1", False), (1.0, [1.0], False), (1.0, None, False), (3, 4.0, True),
    (3, 1e308, False), (3, -1e308, False), (3, 2 ** 64, False), (1.0, 1e17, False), (1.0, -2.0 ** 53, True),
    ((0.0, 0.0, 0.0), (1e300, 0.0, 0.0), False),
    ("a", "b", True), ("a", 1, False), ("a", "x" * MAX_TEXT, True), ("a", "x" * (MAX_TEXT + 1), False),
    ((0.0, 0.0, 0.0), [1, 2, 3], True), ((0.0, 0.0, 0.0), (1.0, 2.0), False),
    ((0.0, 0.0, 0.0), (1.0, math.nan, 3.0), False), ((0.0, 0.0, 0.0), "abc", False),
    (None, 1, False), (object(), "x", False),
])
def test_value_problem_by_kind(current, value, ok):
    assert (value_problem(current, value) is None) == ok


def _start_app(tmp_path_factory):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    return WorkbenchApp(Workbench.builtin(), port=0, env_map=False, wait_for_browser=False,
                        scenes_dir=tmp_path_factory.mktemp("scenes"),
                        recordings_dir=tmp_path_factory.mktemp("recordings")).start()


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    a = _start_app(tmp_path_factory)
    yield a
    a.stop()


@pytest.fixture
def own_app(tmp_path_factory):
    """A session of its own: the shared one has taken every hostile value of the tests before, and a button those
    sent (a grid started, a scene loaded) may still act on it while a later test runs."""
    a = _start_app(tmp_path_factory)
    yield a
    a.stop()


def applied_after(app, client) -> None:
    """Wait until every message ``client`` sent so far has been handled (a marker value sent after them is
    applied: one connection's messages are dispatched in order)."""
    speed = app.controls.speed
    marker = 0.7 if speed.value != 0.7 else 0.8
    client.set(speed, marker)
    wait_for(lambda: speed.value == marker, what="the marker value")


def test_values_of_the_wrong_kind_are_dropped_and_reported(app, capsys):
    c = app.controls
    client = HostileClient(app)
    try:
        before = (c.speed.value, c.gravity.value, c.color_by.value)
        for handle, bad in ((c.speed, "fast"), (c.speed, None), (c.speed, [1, 2]), (c.speed, math.inf),
                            (c.gravity, 1), (c.color_by, 3), (c.color_by, "x" * (MAX_TEXT + 5))):
            client.set(handle, bad)
        applied_after(app, client)
        assert (c.gravity.value, c.color_by.value) == before[1:]
        assert app.refused_values[(c.speed.label, "not a finite number")] == 4
        assert app.refused_values[(c.gravity.label, "not true/false")] == 1
        assert app.refused_values[(c.color_by.label, "not a text")] == 1
        assert app.refused_values[(c.color_by.label, f"longer than {MAX_TEXT} characters")] == 1
        assert app.callback_errors == {}
        out = capsys.readouterr()
        assert out.out.count(f"refused a value for {c.speed.label!r}") == 1  # one line per element and reason
        assert "Traceback" not in out.err
    finally:
        client.close()


def test_a_huge_number_for_an_int_element_leaves_every_page_connected(app):
    """viser casts a value to its element's type and sends it to every page: 1e308 for an int slider would be a
    309-digit int no page message can carry, ending every page's connection. It is refused first."""
    envs = app.grid.envs
    page = HostileClient(app)  # another page, reading what the server sends
    client = HostileClient(app)
    try:
        before = envs.value
        for bad in (1e308, -1e308, 2 ** 63):
            client.set(envs, bad)
        applied_after(app, client)
        applied_after(app, page)  # the other page still answers
        assert envs.value == before
        assert app.refused_values[(envs.label, "not a finite number")] >= 3
        assert page.closed_by is None and client.closed_by is None
    finally:
        client.close()
        page.close()


def test_a_refused_action_is_said_in_the_status_line(app, capsys):
    """Gravity belongs to a running task: the page says so; nothing is logged."""
    wb, c = app.wb, app.controls
    app.policy.start_task("follow_target")
    wait_for(lambda: wb.policy is not None, what="policy session")
    client = HostileClient(app)
    try:
        client.set(c.gravity, not c.gravity.value)
        wait_for(lambda: "gravity belongs to the task" in app.notice[0], what="the refusal in the notice")
        wait_for(lambda: "gravity belongs to the task" in c.status.content, what="the refusal in the status line")
        assert app.callback_errors == {}
        assert "Traceback" not in capsys.readouterr().err
    finally:
        client.close()
        wb.stop_policy()


def test_an_unexpected_error_is_said_and_logged_once(app, capsys):
    calls = []

    def broken(_event) -> None:
        calls.append(1)
        raise KeyError("no such thing")

    btn = app.server.gui.add_button("broken (test)")
    btn.on_click(broken)
    client = HostileClient(app)
    try:
        for n in (1, 2, 3):  # one at a time: clicks sent while one is waiting would be coalesced
            client.click(btn)
            wait_for(lambda n=n: len(calls) == n and sum(app.callback_errors.values()) == n,
                     what=f"failed action {n}")
        assert [k[0] for k in app.callback_errors] == ["KeyError"]
        assert "that action failed: KeyError" in app.notice[0]
        out = capsys.readouterr()
        assert out.out.count("a page action failed (KeyError") == 1
        assert out.err.count("Traceback") == 1
    finally:
        client.close()
        btn.remove()



def _drag(name: str, phase: str, start, end):
    from viser import _messages as vm

    return vm.SceneNodeDragMessage(phase=phase, name=name, instance_index=None, start_position=tuple(start),
                                   start_screen_pos=(0.5, 0.5), end_position=tuple(end), end_screen_pos=(0.5, 0.5),
                                   button="left", modifier=None, owner="")


def test_drags_on_the_rod_from_a_raw_client_are_checked(own_app):
    """A drag on the tube grabs the rod only at a finite point within reach; a hand moved to a non-finite or far point
    stays where it was; the end lets go. Every refusal is said in the status line."""
    app = own_app
    wb = app.wb
    tube = app.view.rod.grip.name  # the rod's grip takes the drags
    tip = wb.tip
    client = HostileClient(app)
    try:
        client.send(_drag(tube, "start", (math.nan, 0.0, 0.0), tip))
        wait_for(lambda: "grab point must be 3 finite numbers" in app.notice[0], what="a non-finite grab refused")
        assert wb.pull is None
        client.send(_drag(tube, "start", tip, tip))
        wait_for(lambda: wb.pull is not None, what="the rod grabbed at its tip")
        assert wb.pull.node == wb.live.n_nodes - 1
        # a far and an infinite hand, then a good one: applied in order, the bad ones refused (the notice says the
        # last refusal), the hand where the good one put it
        marker = np.asarray(tip) + [0.01, 0.0, 0.0]
        client.send(_drag(tube, "update", tip, (1e6, 0.0, 0.0)))
        client.send(_drag(tube, "update", tip, (math.inf, 0.0, 0.0)))
        client.send(_drag(tube, "update", tip, tuple(marker)))
        wait_for(lambda: wb.pull is not None and np.allclose(wb.pull.pointer, marker), what="the good hand applied")
        assert "hand position must be 3 finite numbers" in app.notice[0]
        assert np.all(np.isfinite(wb.pull.pointer))
        client.send(_drag(tube, "end", tip, tip))
        wait_for(lambda: wb.pull is None, what="let go")
    finally:
        client.close()
        wb.release()
