"""The page reaches files only inside its folders and every value it sends is checked on the server (issue:
"Save scene" wrote anywhere, "Load scene"/"Open recording" read anywhere, dropdown values outside the options
were used, uploads had no limit, a policy path from the page was unpickled).

Values are sent by :class:`HostileClient`, a WebSocket client speaking viser's wire format, so they take the
same path through the server as the page's own messages, without the page's checks."""
from __future__ import annotations

import hashlib
import os
import stat

import pytest
from viser import _messages as vm

from sim import load_scene
from tests.helpers.paths import REPO
from tests.helpers.payloads import rodlab_zip, sb3_zip
from tools.browser import wait_for
from tools.hostile_client import HostileClient
from workbench.session.coloring import QUANTITIES

DEFAULT = REPO / "assets" / "scenes" / "default.toml"


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    root = tmp_path_factory.mktemp("wb")
    (root / "scenes").mkdir()
    (root / "recordings").mkdir()
    app = WorkbenchApp(Workbench.from_path(DEFAULT), port=0, env_map=False, scenes_dir=root / "scenes",
                       recordings_dir=root / "recordings", max_upload_mb=1).start()
    client = HostileClient(app)
    yield app, client, root
    client.close()
    app.stop()


def said(handle, text: str, timeout: float = 20.0) -> None:
    wait_for(lambda: text in handle.content, timeout, what=f"message {text!r} (page shows {handle.content!r})")


def clear(*handles) -> None:
    for h in handles:
        h.content = ""


def test_save_refuses_paths_and_never_touches_files_outside(env):
    app, client, root = env
    ob = app.obstacles
    victim = root / "victim.txt"
    victim.write_text("precious")
    os.chmod(victim, 0o640)
    for name in ("../victim.txt", str(victim), "../../x.toml", "..", "a/b.toml", "a\\b.toml", "x\x00.toml"):
        clear(ob.msg)
        client.set(ob.path, name)
        wait_for(lambda: ob.path.value == name, what="name to arrive")
        client.click(ob.save_btn)
        said(ob.msg, "⚠")
        assert "saved" not in ob.msg.content
    assert victim.read_text() == "precious" and stat.S_IMODE(victim.stat().st_mode) == 0o640
    assert sorted(p.name for p in root.iterdir()) == ["recordings", "scenes", "victim.txt"]
    assert list((root / "scenes").iterdir()) == []


def test_save_never_overwrites_another_file_or_a_shipped_scene(env):
    app, client, root = env
    ob = app.obstacles
    before = hashlib.sha256(DEFAULT.read_bytes()).hexdigest()
    other = root / "scenes" / "mine.toml"
    other.write_text("# someone's scene\n")
    clear(ob.msg)
    client.set(ob.path, "mine")
    wait_for(lambda: ob.path.value == "mine", what="name")
    client.click(ob.save_btn)
    said(ob.msg, "already exists")
    assert other.read_text() == "# someone's scene\n"
    clear(ob.msg)
    client.set(ob.path, "default.toml")
    wait_for(lambda: ob.path.value == "default.toml", what="name")
    client.click(ob.save_btn)
    said(ob.msg, "saved")
    assert (root / "scenes" / "default.toml").is_file()
    assert hashlib.sha256(DEFAULT.read_bytes()).hexdigest() == before
    other.unlink()
    (root / "scenes" / "default.toml").unlink()


def test_load_refuses_paths_and_does_not_echo_file_contents(env):
    app, client, root = env
    ob = app.obstacles
    secret = root / "secret.toml"
    secret.write_text('[sim]\ndt = "TOPSECRET"\n')
    (root / "scenes" / "bad.toml").write_text('[sim]\ndt = "TOPSECRET"\n')
    scene0 = app.wb.scene_path
    for name in ("../secret.toml", str(secret), "/etc/passwd", "../../../../etc/passwd", "nope"):
        clear(ob.msg)
        client.set(ob.path, name)
        wait_for(lambda: ob.path.value == name, what="name")
        client.click(ob.load_btn)
        said(ob.msg, "⚠")
        assert "TOPSECRET" not in ob.msg.content
    assert app.wb.scene_path == scene0
    clear(ob.msg)
    client.set(ob.path, "bad")
    wait_for(lambda: ob.path.value == "bad", what="name")
    client.click(ob.load_btn)
    said(ob.msg, "bad.toml")
    assert "⚠" in ob.msg.content and "TOPSECRET" not in ob.msg.content
    (root / "scenes" / "bad.toml").unlink()


def test_open_recording_only_from_the_list_inside_the_recordings_folder(env):
    app, client, root = env
    rp = app.replay
    outside = root / "outside.rrd"
    outside.write_bytes(b"QQSECRETQQ" * 10)
    (root / "recordings" / "junk.rrd").write_bytes(b"QQSECRETQQ" * 10)
    app.replay.refresh_list()
    assert "junk.rrd" in rp.file.options
    for value in ("../outside.rrd", str(outside), "/etc/passwd"):
        clear(rp.msg)
        client.set(rp.file, value)
        said(rp.msg, "not one of the listed options")
        wait_for(lambda: rp.file.value == "junk.rrd", what="value put back")
        # even with the forged value in place (before it is put back), "Open recording" refuses it
        rp.file._impl.value = value
        assert rp.open_listed() is None and app.wb.mode != "replay"
        wait_for(lambda: rp.file.value == "junk.rrd", what="value put back")
    from workbench.session.files import FileAccessError

    for rel in ("../outside.rrd", str(outside), "a/../../outside.rrd"):
        with pytest.raises(FileAccessError):
            app.files.recording(rel)
    # a listed but unreadable recording: a clear message without the file's bytes
    clear(rp.msg)
    client.set(rp.file, "junk.rrd")
    wait_for(lambda: rp.file.value == "junk.rrd", what="selection")
    client.click(rp.open_btn)
    said(rp.msg, "⚠")
    assert "SECRET" not in rp.msg.content and "QQSE" not in rp.msg.content


def test_dropdown_values_outside_the_options_are_refused(env):
    app, client, _root = env
    c = app.controls
    assert app.view.overlays.color_by == "curvature"
    clear(c.msg)
    client.set(c.color_by, "evil")
    said(c.msg, "not one of the listed options")
    wait_for(lambda: c.color_by.value == "curvature", what="value put back")
    assert app.view.overlays.color_by == "curvature"
    clear(c.msg)
    client.set(c.mode, "../../etc")
    said(c.msg, "not one of the listed options")
    assert app.wb.teleop.mode in ("absolute", "delta")
    s = c.sliders[0][0]
    for bad in (float("nan"), float("inf")):  # not a number: dropped before any callback runs
        n0 = app.refused_values.get((s.label, "not a finite number"), 0)
        client.set(s, bad)
        wait_for(lambda n0=n0: app.refused_values.get((s.label, "not a finite number"), 0) == n0 + 1,
                 what=f"{bad} refused")
    clear(c.msg)
    client.set(s, 1e9)  # a number outside the slider's range: the callback says so
    said(c.msg, "finite number")
    assert abs(app.wb.teleop.values[0, 0]) <= 10


def test_a_client_can_change_values_only(env):
    """viser would apply any attribute a client names (e.g. replace the callback list, skipping the checks)."""
    app, client, _root = env
    c = app.controls
    client.send(vm.GuiUpdateMessage(c.color_by._impl.uuid, {"update_cb": [], "options": ["evil"]}))
    clear(c.msg)
    client.set(c.color_by, "evil")
    said(c.msg, "not one of the listed options")
    assert c.color_by._impl.update_cb and tuple(c.color_by.options) == QUANTITIES


def test_policy_path_from_the_page_is_never_loaded(env, tmp_path):
    app, client, _root = env
    pp = app.policy
    marker = tmp_path / "PWNED"
    for payload in (sb3_zip(tmp_path / "model.zip", marker), rodlab_zip(tmp_path / "p.zip", marker)):
        clear(pp.reward)
        client.set(pp.policy, str(payload))
        said(pp.reward, "not one of the listed options")
        wait_for(lambda: pp.policy.value in pp.policy.options, what="value put back")
        # even with the forged value in place (before it is put back), "Run policy" refuses it
        pp.policy._impl.value = str(payload)
        with pytest.raises(ValueError, match="choose a task and a policy from the lists"):
            pp.start_listed()
        pp.policy._impl.value = pp.policy.options[0]
        assert app.wb.policy is None and not marker.exists()
    # the workbench's own policy loading refuses them too (no unpickling)
    from policies.learning.sac import PolicyLoadError
    from workbench.session.policy_session import PolicySession

    for payload in (tmp_path / "model.zip", tmp_path / "p.zip"):
        with pytest.raises(PolicyLoadError):
            PolicySession("follow_target", payload)
    assert not marker.exists()


def test_oversize_upload_is_refused(env):
    app, client, _root = env
    ob = app.obstacles
    n = len(app.wb.obstacles)
    big = b"solid x\n" * (200 * 1024)  # 1.6 MB > 1 MB limit
    from workbench.panels.guard import _CappedUploads

    # the limit sits in viser's upload bookkeeping (fails if viser's internals change): refused before the
    # bytes are collected, not only after
    assert isinstance(app.server.gui._current_file_upload_states, _CappedUploads)
    clear(ob.msg)
    client.upload(ob.upload, "big.stl", big)
    said(ob.msg, "upload refused: over the limit of 1 MB")
    # a client that declares a small size but sends more is cut off too
    clear(ob.msg)
    client.upload(ob.upload, "liar.stl", big, declared=1000, part=256 * 1024)
    said(ob.msg, "upload refused: over the limit of 1 MB")
    # a value sent after the upload is applied only once every earlier part has been handled (one connection's
    # messages are dispatched in order): then nothing of the refused uploads can still arrive
    speed = app.controls.speed
    marker = 0.3 if speed.value != 0.3 else 0.4
    client.set(speed, marker)
    wait_for(lambda: speed.value == marker, what="a value sent after the refused upload")
    assert list(app.files.uploads.iterdir()) == [] and len(app.wb.obstacles) == n
    assert app.obstacles.receive_upload("big.stl", big) is None and "upload refused" in ob.msg.content
    for name in ("../evil.stl", "a/b.stl", "x.py"):
        assert app.obstacles.receive_upload(name, b"solid x\n") is None
    assert list(app.files.uploads.iterdir()) == []


def test_small_upload_goes_to_the_per_launch_folder_which_is_removed_on_exit(tmp_path):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench
    from workbench.session.obstacles import MESH_DIR

    app = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, scenes_dir=tmp_path / "s")
    up = app.files.uploads
    try:
        dest = app.obstacles.receive_upload("torus.stl", (MESH_DIR / "torus.stl").read_bytes())
        assert dest is not None and dest.parent == up and app.wb.obstacles[-1].mesh == str(dest)
        assert stat.S_IMODE(dest.stat().st_mode) & 0o077 != 0o077
    finally:
        app.stop()
    assert not up.exists()


def test_first_save_of_a_shipped_scene_goes_to_the_scenes_folder_under_a_new_name(env):
    app, client, root = env
    ob = app.obstacles
    clear(ob.msg)
    client.set(ob.path, "default")
    wait_for(lambda: ob.path.value == "default", what="name")
    client.click(ob.load_btn)
    said(ob.msg, "loaded")
    assert app.wb.scene_path == DEFAULT
    wait_for(lambda: ob.path.value == "default_edited.toml", what="new name proposed")
    clear(ob.msg)
    client.click(ob.save_btn)
    said(ob.msg, "saved")
    out = root / "scenes" / "default_edited.toml"
    assert load_scene(out).obstacles == load_scene(DEFAULT).obstacles
    assert app.wb.scene_path == out
    out.unlink()
