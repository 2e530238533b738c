"""The threads of a workbench session: stopping the session ends every thread it started (a running grid's
stepping thread would otherwise keep stepping and holding memory in the process), and two threads drawing at
once (the stepping thread and a video being recorded) never mix parts of two frames."""
from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest

from tools.browser import wait_for


def _alive(name: str) -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == name and t.is_alive()]


@pytest.fixture
def app(tmp_path):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    a = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, wait_for_browser=False,
                     scenes_dir=tmp_path / "scenes", recordings_dir=tmp_path / "recordings").start()
    yield a
    a.stop()


def test_stop_ends_the_grid_thread(app):
    before = _alive("rodlab-grid")
    app.grid.start("follow_target", "zero", 2)
    wait_for(lambda: app.grid.runner is not None and app.grid.runner.frames >= 2, what="the grid running")
    runner = app.grid.runner
    assert len(_alive("rodlab-grid")) == len(before) + 1
    app.stop()
    assert not runner.alive
    assert app.grid.runner is None and app.grid.session is None
    assert _alive("rodlab-grid") == before
    # the stepping thread ends too (once the kernels it may still be compiling are compiled)
    wait_for(lambda: not app.thread._thread.is_alive(), what="the stepping thread ended")


def test_frames_drawn_from_two_threads_are_each_drawn_whole(app):
    """Each thread draws its own frames (the rod shifted by its own offset) while the stepping thread draws the
    live one; a render hook reads the tip frame the view has just drawn: it is always at the tip of the hook's
    frame, never at another thread's."""
    app.view.overlays.tip_frame = True
    base = app.wb.frame()
    assert base.m1 is not None and base.m2 is not None
    wrong: list = []

    def check(fr) -> None:
        # (viser skips a pose within np.allclose's default tolerances of the one it holds: compare as it does)
        if not np.allclose(app.view.rod.tip_frame.position, fr.node_pos[-1]):
            wrong.append(fr.time)

    app.render_hooks.append(check)
    try:
        def draw(k: int) -> None:
            fr = dataclasses.replace(base, node_pos=base.node_pos + [0.1 * k, 0.0, 0.0], time=float(k))
            for _ in range(60):
                app._render(fr)

        threads = [threading.Thread(target=draw, args=(k,)) for k in (1, 2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        app.render_hooks.remove(check)
    assert wrong == []


def test_a_late_sync_of_the_playing_box_does_not_pause_the_session(app):
    """The Playing box only shows the session's state when the server sets it: a page action that read "paused"
    (a Rewind) and shows it after another thread started the session again must not pause it (the page's own
    clicks still do)."""
    wb, box = app.wb, app.controls.playing
    wb.set_playing(True)
    app.controls.set_quiet(box, False)  # the late sync of a state read before the session was started again
    assert wb.playing and not box.value
    box.value = True  # what a click on the page does: the callback runs
    box.value = False
    assert not wb.playing


def test_rebuilding_the_scene_nodes_while_drawing_never_writes_to_a_removed_node(app):
    """A scene change rebuilds the rod's rest shape and control beads and the boundary glyphs (in a page callback's
    thread) while frames are drawn (the stepping thread, here also a second drawing thread): a draw never writes to a
    node the rebuild has just removed (each view's nodes are rebuilt or drawn by one thread at a time)."""
    from pathlib import Path

    app.wb.load_scene(Path(__file__).resolve().parents[3] / "assets" / "scenes" / "strip_tip_load.toml")
    errors: list = []
    stop = threading.Event()

    def draw() -> None:
        try:
            while not stop.is_set():
                app._render(app.wb.frame())
        except Exception as exc:  # noqa: BLE001 - collected for the assertion
            errors.append(exc)

    t = threading.Thread(target=draw)
    t.start()
    try:
        for _ in range(150):
            app.refresh_rod_scene()
            app.sync_boundary_view()
    finally:
        stop.set()
        t.join()
    assert errors == [] and app.thread.error is None, (errors, app.thread.error)


def test_grids_started_and_stopped_from_several_threads_leave_one_grid_or_none(app):
    """Run grid pressed on two pages at once, and Stop grid meanwhile: the grids are built one at a time, so no
    grid is left stepping in a thread nobody can stop (nor its simulator held), and no node is removed twice."""
    before = _alive("rodlab-grid")
    errors: list[BaseException] = []

    def run(fn) -> None:
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - collected for the assertion
            errors.append(exc)

    starts = [threading.Thread(target=run, args=(lambda: app.grid.start("follow_target", "zero", 2),))
              for _ in range(3)]
    for t in starts:
        t.start()
    for t in starts:
        t.join()
    assert not errors
    assert len(_alive("rodlab-grid")) == len(before) + 1
    stops = [threading.Thread(target=run, args=(app.grid.stop,)) for _ in range(3)]
    for t in stops:
        t.start()
    for t in stops:
        t.join()
    assert not errors and app.grid.session is None and app.grid.view is None
    wait_for(lambda: _alive("rodlab-grid") == before, what="no grid thread left")


def test_ghosts_shown_and_removed_from_several_threads_while_drawing(app):
    """Show ghost, Ghost of a policy and Remove ghost on different callback threads while the stepping thread draws
    the ghost each frame: each ghost is drawn whole or not at all (no write to a removed node), and one is left."""
    from workbench.session.compare import PolicyEpisode

    N = app.wb.live.model.node_count
    x = np.zeros((20, N, 3))
    x[:, :, 2] = np.linspace(0.0, 1.0, N)
    ep = PolicyEpisode(x, np.linspace(0.0, 1.0, 20), None, 0.01, {"task": "", "policy": "test"})
    errors: list[BaseException] = []
    app.callback_errors.clear()

    def run(fn, n: int) -> None:
        try:
            for _ in range(n):
                fn()
                app.request_render()
        except BaseException as exc:  # noqa: BLE001 - collected for the assertion
            errors.append(exc)

    app.wb.set_playing(True)
    threads = [threading.Thread(target=run, args=(lambda: app.compare.show(ep, label="g"), 15)) for _ in range(2)]
    threads.append(threading.Thread(target=run, args=(app.compare.hide, 15)))
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    app.compare.show(ep, label="last")
    frames = app.thread.frames
    wait_for(lambda: app.thread.frames >= frames + 3, what="frames drawn with the ghost")
    app.wb.set_playing(False)
    assert not errors and not app.callback_errors and app.thread.error is None
    assert app.render_hooks.count(app.compare._draw) == 1
    ghost_nodes = [n for n in app.server.scene._handle_from_node_name if n.startswith("/ghost/")]
    assert len(ghost_nodes) == 3, ghost_nodes
