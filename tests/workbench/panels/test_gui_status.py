"""What the page says about the session without a browser: the status line says when the live session is paused,
and the Gravity box shows whether gravity acts (greyed out where there is none to switch, or it is the task's)."""
from __future__ import annotations

import pytest

from sim import load_scene
from sim.support.assets import asset_path
from tests.workbench.conftest import make_app
from tools.browser import wait_for
from workbench.session.core import Workbench
from workbench.session.policy_session import PolicySession


@pytest.fixture
def app(tmp_path):
    a = make_app(wait_for_browser=False, recordings_dir=tmp_path / "r", scenes_dir=tmp_path / "s")
    yield a
    a.stop()


def test_status_line_says_paused(app):
    wait_for(lambda: not app.compiling, what="the kernels loaded")
    app.wb.set_playing(False)
    app.controls.update_status()
    assert app.controls.status.content.splitlines()[0].rstrip().endswith(" · paused")
    app.wb.set_playing(True)
    app.controls.update_status()
    assert "paused" not in app.controls.status.content.splitlines()[0]


def test_gravity_box_follows_the_scene_and_the_task(app):
    box = app.controls.gravity
    assert box.value is True and not box.disabled  # the arm hangs under gravity
    app.wb.load_scene(asset_path("scenes/curl_self_contact.toml"))
    assert box.value is False and box.disabled  # a scene without gravity: nothing to switch
    app.wb.load_scene(asset_path("scenes/arm.toml"))
    assert box.value is True and not box.disabled
    app.wb.start_policy(PolicySession("follow_target", "zero", seed=0))
    assert box.disabled  # the task's own
    app.wb.stop_policy()
    assert not box.disabled


def test_a_scene_without_gravity_opens_with_the_box_unticked(tmp_path):
    spec = load_scene(asset_path("scenes/cantilever_dynamic.toml"))
    a = make_app(Workbench(spec), wait_for_browser=False, recordings_dir=tmp_path / "r", scenes_dir=tmp_path / "s")
    try:
        assert a.controls.gravity.value is False and a.controls.gravity.disabled
    finally:
        a.stop()
