"""A WebSocket client that speaks viser's wire format directly, as a hostile page or script could: it sends
any value for any GUI element, and any upload, without the page's own checks."""
from __future__ import annotations

import threading
import time
import uuid

import msgspec
import viser
from viser import _messages as vm
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tools.browser import WAIT_BOUND_S


class HostileClient:
    """``read`` (default): a background thread reads and drops what the server sends, as a page that keeps up
    does; without it nothing is read, the client stalls after a few messages and answers no keepalive ping (the
    server then drops it). :attr:`closed_by` is the close that ended the connection, once it ended."""

    def __init__(self, app, *, origin: str | None = None, read: bool = True):
        headers = {"Origin": origin} if origin else {}
        self.app = app
        self.closed_by: ConnectionClosed | None = None
        self._ended = threading.Event()
        before = set(app.server.get_clients())
        self.ws = connect(f"ws://127.0.0.1:{app.port}/", subprotocols=[f"viser-v{viser.__version__}"],
                          additional_headers=headers, max_size=None, open_timeout=WAIT_BOUND_S)
        if read:
            threading.Thread(target=self._drain, daemon=True, name="hostile-client-reader").start()
        # viser registers a client (and runs GUI callbacks for it) after its first camera message
        self.send(vm.ViewerCameraMessage(wxyz=(1.0, 0.0, 0.0, 0.0), position=(1.0, -1.0, 1.0), fov=1.0, near=0.01,
                                         far=100.0, image_height=480, image_width=640, look_at=(0.0, 0.0, 0.5),
                                         up_direction=(0.0, 0.0, 1.0)))
        # an outer bound only (the tests' one): the wait ends when the client is registered; after a soak the
        # server may first work through a backlog of the last session's messages
        t_end = time.monotonic() + WAIT_BOUND_S
        while not set(app.server.get_clients()) - before and time.monotonic() < t_end:
            time.sleep(0.02)
        if not set(app.server.get_clients()) - before:
            raise TimeoutError("the server did not register the client")

    def send(self, msg: vm.Message) -> None:
        self.ws.send(msgspec.msgpack.encode(msg.as_serializable_dict()))

    def set(self, handle, value) -> None:
        """What the page sends when the user changes ``handle`` (or a forged value)."""
        self.send(vm.GuiUpdateMessage(handle._impl.uuid, {"value": value}))

    def click(self, button) -> None:
        self.set(button, True)

    def upload(self, button, name: str, content: bytes, *, declared: int | None = None,
               part: int = 1 << 20) -> None:
        parts = [content[i:i + part] for i in range(0, len(content), part)] or [b""]
        tid = str(uuid.uuid4())
        self.send(vm.FileTransferStartUpload(button._impl.uuid, tid, name, "application/octet-stream", len(parts),
                                             len(content) if declared is None else declared))
        for i, c in enumerate(parts):
            self.send(vm.FileTransferPart(button._impl.uuid, tid, i, c))

    def _drain(self) -> None:
        try:
            while True:
                self.ws.recv()
        except ConnectionClosed as e:
            self.closed_by = e
        finally:
            self._ended.set()

    def wait_closed(self, bound: float = 600.0) -> ConnectionClosed:
        """The close that ends the connection (waits for it; ``bound`` only guards against a hang)."""
        if not self._ended.wait(bound):
            raise TimeoutError(f"the connection did not end within {bound:.0f} s")
        if self.closed_by is None:
            raise RuntimeError("the connection ended without a close")
        return self.closed_by

    def close(self) -> None:
        self.ws.close()
