"""Fixtures for the workbench tests.

Browser tests share ONE headless Chromium, ONE in-process workbench server (port 0, no HDRI) and ONE
page for the whole session (page loads are the slow part on a 2-core box); the ``wb_page`` fixture
puts the workbench back into a clean teleop state before each test.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from playwright.sync_api import expect

from tools.browser import WAIT_MS

# Playwright's assertions wait on the page's state up to the same outer bound as tools.browser.wait_for
expect.set_options(timeout=WAIT_MS)

SHOTS = Path(__file__).resolve().parents[2] / "docs" / "screenshots"


@pytest.fixture(scope="session")
def browser():
    from tools.browser import ChromiumMissing, chromium_path, launch

    try:
        chromium_path()
    except ChromiumMissing as exc:
        pytest.fail(str(exc), pytrace=False)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = launch(p)
        yield b
        b.close()


def make_app(wb=None, **kw):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    wb = wb if wb is not None else Workbench.builtin()
    return WorkbenchApp(wb, port=0, env_map=False, **kw).start()


@pytest.fixture(scope="session")
def shared(browser, tmp_path_factory):
    """(app, page) shared by the browser tests."""
    from tools.browser import open_page

    app = make_app(recordings_dir=tmp_path_factory.mktemp("recordings"), scenes_dir=tmp_path_factory.mktemp("scenes"))
    page = open_page(browser, app, width=960, height=640)
    yield app, page
    page.close()
    app.stop()


@pytest.fixture
def wb_page(shared):
    """The shared (app, page), back in a clean teleop state: no replay, no policy, no obstacles."""
    app, page = shared
    wb = app.wb
    wb.close_replay()
    wb.stop_policy()
    while wb.obstacles:
        wb.delete_obstacle(len(wb.obstacles) - 1)
    app.controls.reach.value = False
    app.controls.show_reach(False)
    wb.set_teleop_mode("absolute")
    app.view.overlays.control_points = True  # the view's defaults, whatever a failed test left
    app.controls.color_by.value = "curvature"
    wb.reset()
    wb.set_playing(True)
    app.sync_obstacle_view()
    app.controls.sync_sliders()
    app.request_render()
    app.thread.error = None
    yield app, page
    # the real page only ever sends the message types the server accepts (workbench.panels.guard.PAGE_MESSAGES)
    assert app.messages.refused == [], f"the page sent refused message types: {app.messages.refused}"
    # and nothing failed in the stepping thread (it shows the error in the page and pauses: never in a test)
    assert app.thread.error is None, f"the stepping thread failed: {app.thread.error!r}"


@pytest.fixture(scope="session")
def shots_dir(tmp_path_factory) -> Path:
    """Where browser tests save their screenshots: a temporary folder, or docs/screenshots/ (the README's
    pictures) when RODLAB_UPDATE_SCREENSHOTS=1, so a plain test run never modifies tracked files."""
    if os.environ.get("RODLAB_UPDATE_SCREENSHOTS") == "1":
        SHOTS.mkdir(parents=True, exist_ok=True)
        return SHOTS
    return tmp_path_factory.mktemp("screenshots")
