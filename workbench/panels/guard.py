"""Server-side checks of the values the page sends (the browser is not trusted).

viser applies a client's update to a GUI handle (``handle.value``) before the handle's callbacks run, and
checks neither a dropdown value against its options nor a slider value against its range. Every callback
of the workbench therefore starts with one of these checks; a refused value is put back to the last good
one (the page shows it again) and the panel says why.

    guard = GuiGuard()
    sel = guard.track(gui.add_dropdown(...))
    @sel.on_update
    def _(_e):
        if not guard.option(sel, say):
            return
        ...
"""
from __future__ import annotations

import math
import threading
from typing import Any, Callable

import numpy as np

Say = Callable[[str], None]


class GuiGuard:
    """Remembers the last accepted value of each tracked handle and puts it back on a refused update."""

    def __init__(self):
        self._last: dict[int, Any] = {}
        self._lock = threading.Lock()

    def track(self, handle):
        with self._lock:
            self._last[id(handle)] = handle.value
        return handle

    def accept(self, handle) -> None:
        """The handle's current value is good (also call after setting options/values server-side)."""
        with self._lock:
            self._last[id(handle)] = handle.value

    def _revert(self, handle, say: Say, why: str) -> bool:
        with self._lock:
            last = self._last.get(id(handle))
        if last is not None and handle.value != last:
            handle.value = last  # runs the callbacks again, with the good value
        say(f"⚠ {why}")
        return False

    def option(self, handle, say: Say) -> bool:
        """A dropdown value is one of its options."""
        v = handle.value
        if isinstance(v, str) and v in tuple(handle.options):
            self.accept(handle)
            return True
        return self._revert(handle, say, f"{handle.label}: not one of the listed options")

    def number(self, handle, say: Say, lo: float | None = None, hi: float | None = None) -> bool:
        """A finite number within [lo, hi] (default: the slider's own min/max)."""
        v = handle.value
        lo = getattr(handle, "min", None) if lo is None else lo
        hi = getattr(handle, "max", None) if hi is None else hi
        ok = (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
              and (lo is None or v >= lo) and (hi is None or v <= hi))
        if ok:
            self.accept(handle)
            return True
        return self._revert(handle, say, f"{handle.label}: needs a finite number in [{lo}, {hi}]")


def finite_pose(position, wxyz, *, limit: float = 100.0) -> tuple[np.ndarray, np.ndarray] | None:
    """(position (3,), unit wxyz (4,)) from a gizmo update, or None when not finite / too far / zero quaternion."""
    try:
        p = np.asarray(position, dtype=np.float64).reshape(3)
        q = np.asarray(wxyz, dtype=np.float64).reshape(4)
    except (TypeError, ValueError):
        return None
    n = float(np.linalg.norm(q))
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q)) and n > 1e-9 and np.max(np.abs(p)) <= limit):
        return None
    return p, q / n


class _CappedUploads(dict):
    """viser's table of uploads in flight (transfer id -> state). An upload whose declared or received size
    passes the limit is dropped at once (its parts are then ignored), so its bytes are never collected."""

    def __init__(self, limit: int, on_refused: Callable[[str, int], None]):
        super().__init__()
        self.limit, self.on_refused = limit, on_refused

    def __setitem__(self, key, state) -> None:
        if isinstance(state, dict) and int(state.get("total_bytes") or 0) > self.limit:
            self.on_refused(str(state.get("filename", "")), int(state["total_bytes"]))
            return
        if isinstance(state, dict):
            state = _CappedTransfer(self, key, state)
        super().__setitem__(key, state)


class _CappedTransfer(dict):
    def __init__(self, table: _CappedUploads, key, state: dict):
        super().__init__(state)
        self._table, self._key = table, key

    def __setitem__(self, name, value) -> None:
        super().__setitem__(name, value)
        if name == "transferred_bytes" and int(value) > self._table.limit:
            self["parts"].clear()
            self._table.pop(self._key, None)
            self._table.on_refused(str(self.get("filename", "")), int(value))


def cap_uploads(server, limit: int, on_refused: Callable[[str, int], None]) -> bool:
    """Install the upload size limit in viser's upload bookkeeping (returns False if viser changed and only
    the check of the finished upload remains)."""
    gui = server.gui
    if not isinstance(getattr(gui, "_current_file_upload_states", None), dict):
        return False
    gui._current_file_upload_states = _CappedUploads(limit, on_refused)
    return True


MAX_TEXT = 1000  # characters of a text value from the page (names of scenes, recordings, frames)
MAX_NUMBER = 2.0 ** 53  # magnitude of a number from the page: viser casts a value to its element's type (an
# int element turns 1e308 into a 309-digit int) and sends it to every page; msgpack encodes no int beyond 64 bits,
# so such a value would end every page's connection. Every number of the page's elements is far below this.


def value_problem(current, value) -> str | None:
    """Why ``value`` cannot be a value of a GUI element whose value is now ``current``, or None when it can:
    the same kind (a switch or button: a bool; a number: a finite int/float of magnitude at most
    :data:`MAX_NUMBER`; a text: a string of at most
    :data:`MAX_TEXT` characters; a vector or colour: as many finite numbers). Ranges and options are the
    panels' checks (they say why in the page); this one keeps values of the wrong kind out of viser's casts
    and the callbacks."""
    def finite_number(x) -> bool:
        return (isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                and abs(x) <= MAX_NUMBER)

    if isinstance(current, bool):
        return None if isinstance(value, bool) else "not true/false"
    if isinstance(current, (int, float)):
        return None if finite_number(value) else "not a finite number"
    if isinstance(current, str):
        if not isinstance(value, str):
            return "not a text"
        return None if len(value) <= MAX_TEXT else f"longer than {MAX_TEXT} characters"
    if isinstance(current, tuple):
        ok = (isinstance(value, (list, tuple)) and len(value) == len(current)
              and all(finite_number(x) for x in value))
        return None if ok else f"not {len(current)} finite numbers"
    return "this element takes no value from the page"  # e.g. an upload button (files come as transfers)


def resend_value(handle) -> None:
    """Send the handle's value to every page again. viser sends a value only when it changes, so a value the
    server set that crossed a page's own change on the wire (the page then shows the server's older value while the
    server holds the page's) is never corrected otherwise."""
    handle._queue_update("value", handle.value)


def only_value_updates(server, on_refused: Callable[[str, str], None] | None = None) -> bool:
    """Let clients change only the ``value`` of a GUI element, and only to a value of the element's kind
    (:func:`value_problem`; a refused update is dropped and reported as (label, why)). viser applies any
    attribute a client names in a GUI update (its callback list, its options, ...) and casts the value with the
    current value's type; the page itself only ever sends ``value``. Returns False if viser changed and the
    filter could not be installed."""
    from viser import _messages as vm

    gui = server.gui
    ws, handler = server._websock_server, gui._handle_gui_updates
    if handler not in ws._incoming_handlers.get(vm.GuiUpdateMessage, []):
        return False
    if not isinstance(getattr(gui, "_gui_input_handle_from_uuid", None), dict):
        return False
    ws.unregister_handler(vm.GuiUpdateMessage, handler)

    async def values_only(client_id, message) -> None:
        if "value" not in message.updates:
            return
        handle = gui._gui_input_handle_from_uuid.get(message.uuid)
        if handle is None:
            return
        value = message.updates["value"]
        why = value_problem(handle._impl.value, value)
        if why is not None:
            if on_refused is not None:
                on_refused(str(getattr(handle, "label", "") or message.uuid), why)
            return
        message.updates = {"value": value}
        await handler(client_id, message)

    ws.register_handler(vm.GuiUpdateMessage, values_only)
    return True


# The message types the workbench's page sends (docs/architecture.md, "Security"): values of GUI elements and
# button presses, mesh uploads, clicks on scene nodes, drags on the rod (the hand pulling it), the obstacle
# gizmo, the camera and the screenshot's render. viser's server also handles share-tunnel requests (which ask a
# public relay to publish the session), button-hold, form, command-palette, pointer and local-storage messages;
# the page has no control that sends them, so a client that does is not the page.
PAGE_MESSAGES = (
    "GuiUpdateMessage",
    "FileTransferStartUpload",
    "FileTransferPart",
    "SceneNodeClickMessage",
    "SceneNodeDragMessage",
    "TransformControlsUpdateMessage",
    "TransformControlsDragStartMessage",
    "TransformControlsDragEndMessage",
    "ViewerCameraMessage",
    "GetRenderResponseMessage",
)
REFUSED_CLOSE_CODE = 1008  # WebSocket "policy violation"


class MessageGuard:
    """Lets through only the message types of :data:`PAGE_MESSAGES`; any other type closes the sender's
    connection with code 1008 and a reason naming the type, before any handler of viser's sees it.

    viser hands each incoming message to the server's dispatcher and to the connection's; both are wrapped
    (the connection's when it opens, before its first message is read). The share-tunnel handlers are also
    removed outright, so no code path left in viser can open a tunnel."""

    def __init__(self, allowed=PAGE_MESSAGES):
        from viser import _messages as vm

        self.allowed = frozenset(getattr(vm, name) for name in allowed)
        self.refused: list[str] = []  # type names, in order (for the log and tests)
        self._lock = threading.Lock()

    def install(self, server) -> bool:
        """Install on a running ``viser.ViserServer``; False if viser changed and the guard could not be put
        in place (the caller must then not serve)."""
        from viser import _messages as vm

        ws = server._websock_server
        needed = ("_handle_incoming_message", "_incoming_handlers", "on_client_connect", "_live_connections")
        if not all(hasattr(ws, name) for name in needed):
            return False
        for share in (vm.ShareUrlRequest, vm.ShareUrlDisconnect):
            ws._incoming_handlers.pop(share, None)
        self._wrap(ws, refuse=True, connections=ws._live_connections)
        ws.on_client_connect(lambda conn: self._wrap(conn, refuse=False))
        return True

    def _wrap(self, dispatcher, *, refuse: bool, connections=None) -> None:
        inner = dispatcher._handle_incoming_message

        async def checked(client_id, message) -> None:
            if type(message) in self.allowed:
                await inner(client_id, message)
            elif refuse:  # the server's dispatcher answers; the connection's only drops the message
                await self._refuse(connections, client_id, type(message).__name__)

        dispatcher._handle_incoming_message = checked

    async def _refuse(self, connections, client_id, name: str) -> None:
        with self._lock:
            self.refused.append(name)
        print(f"rodlab workbench: refused a {name} message from client {client_id} (not sent by the page); "
              "connection closed", flush=True)
        conn = connections.get(client_id)
        if conn is not None:
            await conn.close(REFUSED_CLOSE_CODE, f"rodlab workbench: {name} is not accepted"[:120])


class _GuardedExecutor:
    """viser's callback thread pool, with each callback run through ``report`` on an exception, one call of each
    callback at a time, and at most one call of each callback waiting: a client sending faster than a callback
    runs (a slider dragged, a button pressed again while its action runs, a hostile client at hundreds of messages
    per second) replaces the waiting call's arguments with its newest instead of queueing another (callbacks read
    their element's current value, so the newest call is the one that counts), and the waiting call starts when
    the running one returns, on the same thread. The queue is then bounded by the number of callbacks, not by the
    client's rate, and no action overlaps itself (two builds of one grid, two ghosts drawn at once)."""

    def __init__(self, inner, report: Callable[[BaseException], None]):
        self._inner, self._report = inner, report
        self._lock = threading.Lock()
        self._waiting: dict[Any, tuple[tuple, dict]] = {}  # callback -> newest (args, kwargs) not yet started
        self._active: set = set()  # callbacks with a call running or submitted to the pool
        self._running = 0
        self.coalesced = 0  # calls folded into a waiting call of the same callback

    def submit(self, fn, /, *args, **kwargs):
        from concurrent.futures import Future

        with self._lock:
            folded = fn in self._waiting
            self._waiting[fn] = (args, kwargs)
            if folded:
                self.coalesced += 1
            if folded or fn in self._active:  # the running call's thread starts it next
                done: Future = Future()
                done.set_result(None)
                return done
            self._active.add(fn)
        return self._inner.submit(self._run, fn)

    def _run(self, fn) -> None:
        again = True
        while again:
            with self._lock:
                a, kw = self._waiting.pop(fn)
                self._running += 1
            try:
                fn(*a, **kw)
            except Exception as exc:  # noqa: BLE001 - reported on the page and (unexpected ones) in the log
                self._report(exc)
            except BaseException:  # the thread is going away: its waiting call goes with it (finally frees fn)
                with self._lock:
                    self._waiting.pop(fn, None)
                raise
            finally:
                with self._lock:
                    self._running -= 1
                    again = fn in self._waiting
                    if not again:
                        self._active.discard(fn)

    def waiting(self) -> int:
        """Callbacks waiting to run."""
        with self._lock:
            return len(self._waiting)

    def busy(self) -> int:
        """Callbacks waiting or running."""
        with self._lock:
            return len(self._waiting) + self._running

    def __getattr__(self, name):
        return getattr(self._inner, name)


def guard_callbacks(server, report: Callable[[BaseException], None]) -> bool:
    """Run every GUI and scene callback of ``server`` so that an exception reaches ``report`` (the page says
    what went wrong) instead of a traceback in viser's thread pool. False if viser changed."""
    apis = (server.gui, server.scene)
    if not all(hasattr(api, "_thread_executor") for api in apis):
        return False
    for api in apis:
        api._thread_executor = _GuardedExecutor(api._thread_executor, report)
    return True
