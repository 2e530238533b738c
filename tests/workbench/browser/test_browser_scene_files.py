"""Real browser: the untouched default scene is saved from the page and loaded back (issue: one click on
"Save scene" replaced the user's scene with a file that could not be loaded)."""
from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from sim import load_scene
from tools.browser import expand_folder, wait_for

pytestmark = pytest.mark.browser
DEFAULT = Path(__file__).resolve().parents[3] / "assets" / "scenes" / "default.toml"


def test_save_the_default_scene_from_the_page_and_load_it_back(wb_page):
    app, page = wb_page
    wb, ob = app.wb, app.obstacles
    shipped = hashlib.sha256(DEFAULT.read_bytes()).hexdigest()
    expand_folder(page, "Obstacles", "Save scene")
    label = page.locator("label").filter(has_text="Scene file").first
    field = label.locator("xpath=ancestor::div[.//input][1]//input").first  # the text input of that row
    field.fill("default")
    wait_for(lambda: ob.path.value == "default", what="scene name to reach the server")
    ob.msg.content = ""
    page.get_by_role("button", name="Load scene").click()
    wait_for(lambda: "loaded" in ob.msg.content, timeout=30, what="shipped default scene loaded")
    assert wb.scene_path == DEFAULT
    n = len(wb.obstacles)
    assert n == len(load_scene(DEFAULT).obstacles) > 0
    # the page proposes a new name in the scenes folder: the shipped file is never written
    wait_for(lambda: field.input_value() == "default_edited.toml", what="new name shown in the page")
    page.get_by_role("button", name="Save scene").click()
    out = app.files.scenes / "default_edited.toml"
    wait_for(out.is_file, timeout=30, what="saved scene file")
    wait_for(lambda: "saved" in ob.msg.content, what="saved message")
    saved, orig = load_scene(out), load_scene(DEFAULT)
    assert (saved.sim, saved.rod, saved.contact, saved.obstacles) == (orig.sim, orig.rod, orig.contact, orig.obstacles)
    assert hashlib.sha256(DEFAULT.read_bytes()).hexdigest() == shipped
    # change the session, then load the saved file back from the page
    wb.delete_obstacle(0)
    assert len(wb.obstacles) == n - 1
    ob.msg.content = ""
    page.get_by_role("button", name="Load scene").click()
    wait_for(lambda: "loaded" in ob.msg.content, timeout=30, what="saved scene loaded back")
    assert wb.scene_path == out and len(wb.obstacles) == n
    assert [e.kind for e in wb.obstacles] == [type(o).__name__.replace("Spec", "").lower() for o in orig.obstacles]
    out.unlink()
