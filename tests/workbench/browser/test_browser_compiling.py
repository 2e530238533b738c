"""Real browser: on the first start the kernels compile for minutes before the first step; meanwhile the status line
says so and what is being compiled (it said "paused until a browser connects" with a browser connected). The
compile is ``sim.compile_kernels``, run by the app in its sim thread; a stand-in that waits on the test plays a slow
one."""
from __future__ import annotations

import threading

import pytest

from tools.browser import open_page, wait_for

pytestmark = pytest.mark.browser


def test_status_says_compiling_kernels(browser, tmp_path, monkeypatch):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    done, stages = threading.Event(), []

    def slow_warmup(*, verbose: bool = False, on_stage=None) -> float:
        for what in ("the 3D step kernel", "the 2D step kernel"):
            stages.append(what)
            if on_stage is not None:
                on_stage(what)
            done.wait(600)  # until the test has seen the page
        return 0.0

    monkeypatch.setattr("sim.compile_kernels", slow_warmup)
    app = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, recordings_dir=tmp_path / "rec",
                       scenes_dir=tmp_path / "scenes").start()
    try:
        page = open_page(browser, app, width=960, height=640)
        try:
            wait_for(lambda: not app.waiting_for_browser, what="the page connected")
            status = page.get_by_text("compiling kernels: the 3D step kernel", exact=False)
            status.first.wait_for()
            assert "paused until a browser connects" not in app.controls.status.content
            assert app.wb.frame_index == 0
            done.set()
            wait_for(lambda: app.wb.playing and app.wb.frame_index > 2, what="the session stepping after the compile")
            wait_for(lambda: "compiling" not in app.controls.status.content, what="the status without the compile")
            assert stages == ["the 3D step kernel", "the 2D step kernel"]
        finally:
            page.close()
    finally:
        done.set()
        app.stop()
