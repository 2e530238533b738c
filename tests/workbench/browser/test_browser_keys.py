"""Real browser: keyboard shortcuts. Space pauses and plays, → steps once (paused), r resets; keys typed into a text
field stay in the field; the shortcuts are listed in the Run tab. The script comes with the page and works through
the page's own controls (no endpoint of its own)."""
from __future__ import annotations

import urllib.request

import pytest
from playwright.sync_api import expect

from tools.browser import expand_folder, wait_for
from workbench.serve.keys import SHORTCUTS

pytestmark = pytest.mark.browser


def _blur(page) -> None:
    page.evaluate("() => { if (document.activeElement) document.activeElement.blur(); }")


def test_space_arrow_and_r(wb_page):
    app, page = wb_page
    wb = app.wb
    expand_folder(page, "Run", "Step")
    expect(page.get_by_text("Keys:", exact=False).first).to_be_visible()
    _blur(page)
    wait_for(lambda: wb.playing, what="playing at the start")
    page.keyboard.press("Space")
    wait_for(lambda: not wb.playing, what="space pauses")
    expect(page.get_by_label("Playing")).not_to_be_checked()
    page.keyboard.press("Space")
    wait_for(lambda: wb.playing, what="space plays again")
    page.keyboard.press("Space")
    wait_for(lambda: not wb.playing, what="space pauses again")
    f0 = wb.frame_index
    for n in (1, 2, 3):
        page.keyboard.press("ArrowRight")
        wait_for(lambda n=n: wb.frame_index == f0 + n, what=f"→ step {n}")
    assert not wb.playing
    page.keyboard.press("r")
    wait_for(lambda: wb.frame_index == 0, what="r resets")
    assert not wb.playing  # a reset keeps the play state


def test_keys_in_a_text_field_are_text(wb_page):
    app, page = wb_page
    wb = app.wb
    expand_folder(page, "Obstacles", "Save scene")
    label = page.locator("label").filter(has_text="Scene file").first
    field = label.locator("xpath=ancestor::div[.//input][1]//input").first  # the text input of that row
    old = field.input_value()
    wait_for(lambda: wb.playing, what="playing")
    field.click()
    field.press("End")
    field.press_sequentially(" r")
    expect(field).to_have_value(old + " r")
    field.press("ArrowRight")
    # the script acts in the key handler itself: had it clicked "Playing", the box would be unticked by now
    expect(page.get_by_label("Playing")).to_be_checked()
    f = wb.frame_index
    wait_for(lambda: wb.frame_index > f, what="frames keep counting")
    assert wb.playing
    field.fill(old)
    field.press("Enter")
    _blur(page)


def test_script_is_served_with_the_page_only(wb_page):
    app, _page = wb_page
    with urllib.request.urlopen(app.url, timeout=600) as r:
        page = r.read().decode()
    assert page.count('data-rodlab="keys"') == 1
    for key, (_kind, label) in SHORTCUTS.items():
        assert f'"{label}"' in page
    assert page.index('data-rodlab="keys"') < page.rindex("</body>")
    # gzip-encoded page (what browsers ask for) carries it too
    req = urllib.request.Request(app.url, headers={"Accept-Encoding": "gzip"})
    with urllib.request.urlopen(req, timeout=600) as r:
        import gzip

        assert r.headers["Content-Encoding"] == "gzip"
        body = r.read()
        assert int(r.headers["Content-Length"]) == len(body)
        assert b'data-rodlab="keys"' in gzip.decompress(body)
