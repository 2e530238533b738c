"""A client may send only the message types the workbench's page sends: viser's share-tunnel request (which
would publish the session on a public relay) and every other type the page has no control for are refused on
the server, over a real WebSocket, before any of viser's handlers runs."""
from __future__ import annotations

import time
from types import SimpleNamespace

import pytest
import viser
import viser._viser as viser_module
from viser import _messages as vm

from tests.helpers.paths import REPO
from tools.hostile_client import HostileClient
from workbench.panels.guard import PAGE_MESSAGES, REFUSED_CLOSE_CODE


class TunnelMarker:
    """Stands in for viser's ViserTunnel: records that a tunnel was asked for and never connects."""

    created: list = []

    def __init__(self, *args, **kwargs):
        TunnelMarker.created.append(args)
        self._status = "failed"

    def on_disconnect(self, fn):
        return fn

    def on_connect(self, fn):
        return fn

    def connect(self):
        pass

    def get_status(self):
        return self._status

    def get_url(self):
        return None

    def close(self):
        self._status = "closed"


@pytest.fixture
def tunnel_marker(monkeypatch):
    TunnelMarker.created = []
    monkeypatch.setattr(viser_module, "ViserTunnel", TunnelMarker)
    return TunnelMarker


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    a = WorkbenchApp(Workbench.builtin(), port=0, env_map=False, scenes_dir=tmp_path_factory.mktemp("scenes"),
                     recordings_dir=tmp_path_factory.mktemp("recordings"))
    yield a
    a.stop()


def refused_messages():
    """One message of each type viser's server handles that the page never sends."""
    return [
        vm.ShareUrlRequest(),
        vm.ShareUrlDisconnect(),
        vm.GuiButtonHoldMessage(uuid="x", frequency=10.0),
        vm.GuiFormSubmitMessage(uuid="x"),
        vm.GuiFormDirtyMessage(uuid="x"),
        vm.CommandTriggerMessage(uuid="x"),
        vm.ScenePointerMessage(event_type="click", ray_origin=(0.0, 0.0, 1.0), ray_direction=(0.0, 0.0, -1.0),
                               screen_pos=((0.5, 0.5),), modifier=None),
        vm.LocalStorageGetItemResponseMessage(value="v", error=None, request_uuid="x"),
    ]


def close_of(client: HostileClient):
    """(code, reason) with which the server closed the client's connection (waits for it)."""
    rcvd = client.wait_closed().rcvd
    assert rcvd is not None, "the connection ended without a close frame from the server"
    return rcvd.code, rcvd.reason


@pytest.mark.parametrize("message", refused_messages(), ids=lambda m: type(m).__name__)
def test_message_the_page_never_sends_is_refused(app, tunnel_marker, message):
    n0 = len(app.messages.refused)
    client = HostileClient(app)
    client.send(message)
    code, reason = close_of(client)
    name = type(message).__name__
    assert code == REFUSED_CLOSE_CODE
    assert reason == f"rodlab workbench: {name} is not accepted"
    assert app.messages.refused[n0:] == [name]
    assert tunnel_marker.created == []
    assert app.server._share_tunnel is None


def test_share_request_opens_a_tunnel_on_an_unguarded_viser_server(tunnel_marker):
    """The marker works: the same message makes a bare viser server ask for a public tunnel."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        client = HostileClient(SimpleNamespace(server=server, port=server.get_port()))
        client.send(vm.ShareUrlRequest())
        t_end = time.monotonic() + 120
        while not tunnel_marker.created and time.monotonic() < t_end:
            time.sleep(0.02)
        client.close()
        assert len(tunnel_marker.created) == 1
        assert tunnel_marker.created[0][0] == "share.viser.studio"
    finally:
        server.stop()


def test_page_messages_still_reach_their_handlers(app):
    """An allowed type after the guard: a GUI value from a raw client still changes the element."""
    client = HostileClient(app)
    try:
        speed = app.controls.speed
        target = 0.5 if speed.value != 0.5 else 0.25
        client.set(speed, target)
        t_end = time.monotonic() + 120
        while speed.value != target and time.monotonic() < t_end:
            time.sleep(0.02)
        assert speed.value == target
    finally:
        client.close()


def test_allowed_set_is_what_the_docs_list():

    text = (REPO / "docs" / "architecture.md").read_text()
    for name in PAGE_MESSAGES:
        assert f"`{name}`" in text, f"docs/architecture.md does not list {name}"
    assert "ShareUrlRequest" in text
