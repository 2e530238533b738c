"""Driving a running workbench app from a test (the server side of a browser test)."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import open_page, wait_for

# The tests' pages: 960x640, at most 5 animation frames a second, and (make_app) no shadows. Software WebGL redraws a
# playing scene as often as it can (1.5 of the 2 cores with shadows, at ~7 frames a second): capped, the page leaves
# the cores to the server and to the tests on the other process.
PAGE_W, PAGE_H, PAGE_FPS = 960, 640, 5.0


def open_test_page(browser, app, *, width: int = PAGE_W, height: int = PAGE_H):
    """A page on ``app`` as the browser tests open them (:data:`PAGE_FPS`)."""
    return open_page(browser, app, width=width, height=height, max_fps=PAGE_FPS)


def set_live_playing(app, on: bool) -> None:
    """Play or pause the live session, its Playing box in the page following (without calling back)."""
    app.wb.set_playing(on)
    app.controls.set_quiet(app.controls.playing, on)


def pause_drawn(app) -> None:
    """Pause the live session and wait until the view has drawn the paused state's frame."""
    wb = app.wb
    set_live_playing(app, False)
    app.request_render()
    wait_for(lambda: app.view.last_frame.time == pytest.approx(float(np.asarray(wb.live.state.time)[0])),
             what="the paused frame drawn")
