"""Driving a running workbench app from a test (the server side of a browser test)."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import wait_for


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
