"""Real browser: the Rewind slider can be used while the session plays. It follows the newest frame until the page
moves it; a frame chosen in the page stays chosen while the session plays on (it was replaced by the newest frame at
the next readout), and Rewind goes back to it and pauses. The Run tab says what Rewind does."""
from __future__ import annotations

import pytest
from playwright.sync_api import expect

from tools.browser import expand_folder, slider_thumb, wait_for
from workbench.panels.policy import REWIND_HELP

pytestmark = pytest.mark.browser


def test_rewind_while_playing(wb_page):
    app, page = wb_page
    wb, pol = app.wb, app.policy
    expand_folder(page, "Run", "Rewind")
    expect(page.get_by_text(REWIND_HELP[:40], exact=False)).to_be_visible()
    # playing: the slider follows the newest frame
    wait_for(lambda: wb.playing and wb.frame_index > 20, timeout=120, what="the session playing")
    wait_for(lambda: int(pol.rewind.value) > 15, what="the slider following the newest frame")
    th = slider_thumb(page, "Rewind to frame")
    th.focus()
    th.press("Home")  # the oldest frame kept
    want = int(pol.rewind.min)
    wait_for(lambda: int(pol.rewind.value) == want, what="the chosen frame on the server")
    # the session plays on, the history grows (the slider's range with it): the chosen frame stays
    f = wb.frame_index
    wait_for(lambda: wb.frame_index > f + 20 and int(pol.rewind.max) > f + 10, timeout=120, what="more frames")
    assert wb.playing and int(pol.rewind.value) == want
    expect(th).to_have_attribute("aria-valuenow", str(want))
    page.get_by_role("button", name="Rewind", exact=True).click()
    wait_for(lambda: not wb.playing and wb.frame_index == want, what="rewound to the chosen frame, paused")
    expect(page.get_by_label("Playing")).not_to_be_checked()
    # playing again, the slider follows the newest frame again
    page.get_by_label("Playing").check()
    wait_for(lambda: wb.playing and int(pol.rewind.value) > want + 10, timeout=120, what="the slider following again")
