"""Who may talk to the workbench server: a check on every HTTP request and WebSocket handshake.

viser serves its page and its WebSocket on one port through one ``websockets.asyncio.server.serve`` call
(``viser/infra/_infra.py``) and offers no option to check a request's ``Host``/``Origin`` or to require a
token. ``websockets`` does offer a ``process_request`` hook on ``serve``; :func:`start_viser` installs
:func:`check_request` there by wrapping ``serve`` for the duration of ``viser.ViserServer(...)`` only (the
server binds before the constructor returns). If viser ever stops calling ``serve`` that way, the wrapper
is never used and :func:`start_viser` refuses to run the server unguarded (``HandshakeGuardMissing``);
tests/workbench/serve/test_handshake.py fails in that case too.

Rules (a request failing one gets ``403 Forbidden``):

* loopback bind (127.0.0.1, ::1, localhost): ``Host`` must be one of ``127.0.0.1:PORT``,
  ``localhost:PORT``, ``[::1]:PORT`` (blocks DNS rebinding: a hostile name resolved to 127.0.0.1 arrives
  with its own name in ``Host``);
* any bind: an ``Origin`` header, when present, must be the page's own origin ``http://<Host>`` (browsers
  always send ``Origin`` on cross-site WebSocket handshakes, so other web pages cannot connect);
* the page (``/``) gets the keyboard-shortcut script of ``workbench.serve.keys`` (static text, no endpoint);
* non-loopback bind: the page and the WebSocket need ``?token=<per-launch random token>`` (the page keeps
  its query string when it opens the WebSocket); the client bundle's static files need no token (they
  are viser's public JavaScript/CSS and hold no state).
"""
from __future__ import annotations

import contextlib
import dataclasses
import http
import io
import ipaddress
import secrets
import socket
import threading
from urllib.parse import parse_qs, urlsplit

from workbench.serve.keys import with_keys

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")
_PATCH_LOCK = threading.Lock()


class HandshakeGuardMissing(RuntimeError):
    """viser no longer starts its server through ``websockets.asyncio.server.serve``: the check is not in place."""


class BindError(RuntimeError):
    """The requested ``--host`` cannot be bound (unknown name, not an address of this machine, ...)."""


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclasses.dataclass
class Guard:
    """The request policy of one server. ``token`` is None on a loopback bind."""

    bound: str
    loopback: bool
    token: str | None
    rejected: int = 0  # requests answered with 403 (for tests)

    @classmethod
    def for_host(cls, host: str) -> "Guard":
        loop = is_loopback(host)
        return cls(bound=host, loopback=loop, token=None if loop else secrets.token_urlsafe(24))

    def url(self, port: int) -> str:
        """The page's address (with the token on a non-loopback bind)."""
        h = self.bound
        if h in ("0.0.0.0", "::", ""):
            h = socket.gethostname()
        elif self.loopback and h == "localhost":
            h = "127.0.0.1"
        if ":" in h:
            h = f"[{h}]"
        return f"http://{h}:{port}/" + (f"?token={self.token}" if self.token else "")

    def why_rejected(self, host: str | None, origin: str | None, target: str, port: int,
                     websocket: bool) -> str | None:
        """None when the request may proceed, else the reason (sent with the 403)."""
        if not host:
            return "missing Host header"
        host = host.strip().lower()
        if self.loopback:
            own = f"[{self.bound}]" if ":" in self.bound else self.bound.lower()
            allowed = {f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}", f"{own}:{port}"}
            if port == 80:
                allowed |= {"127.0.0.1", "localhost", "[::1]"}
            if host not in allowed:
                return f"Host {host[:80]!r} is not this server's loopback address"
        if origin is not None and origin.strip().lower() not in (f"http://{host}", f"https://{host}"):
            return "cross-origin request"
        if self.token is not None:
            path = urlsplit(target).path
            if websocket or path in ("", "/", "/index.html"):
                given = parse_qs(urlsplit(target).query).get("token", [""])[0]
                if not secrets.compare_digest(given.encode(), self.token.encode()):
                    return "missing or wrong token (use the URL printed at start-up)"
        return None

    def process_request(self, connection, request):
        """``websockets`` ``process_request`` hook: a 403 response, or None to go on."""
        headers = request.headers
        try:
            port = int(connection.local_address[1])
        except (TypeError, IndexError, ValueError):
            port = -1
        why = self.why_rejected(headers.get("Host"), headers.get("Origin"), request.path, port,
                                (headers.get("Upgrade") or "").lower() == "websocket")
        if why is None:
            return None
        self.rejected += 1
        return connection.respond(http.HTTPStatus.FORBIDDEN, f"rodlab workbench: {why}\n")


def check_bindable(host: str, port: int) -> None:
    """Raise BindError now (with the reason) when ``host`` cannot be bound, instead of letting viser try
    1000 ports on it and wait forever."""
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        raise BindError(f"cannot serve on --host {host!r}: unknown host name or address ({exc})") from None
    err: OSError | None = None
    for family, kind, proto, _name, addr in infos:
        try:
            with socket.socket(family, kind, proto) as s:
                s.bind((addr[0], 0) + tuple(addr[2:]))
            return
        except OSError as exc:
            err = exc
    raise BindError(f"cannot serve on --host {host!r}: {err.strerror if err else 'no usable address'} "
                    "(use an address of this machine, e.g. 127.0.0.1)")


def page_with_keys(request, response):
    """viser's page with the keyboard-shortcut script of ``workbench.serve.keys`` added (any other response unchanged)."""
    if response is None or getattr(response, "status_code", None) != 200:
        return response
    if urlsplit(request.path).path not in ("", "/", "/index.html"):
        return response

    headers = response.headers
    body = with_keys(response.body, (headers.get("Content-Encoding") or "").lower() == "gzip")
    new_headers = type(headers)(headers)
    del new_headers["Content-Length"]
    new_headers["Content-Length"] = str(len(body))
    return dataclasses.replace(response, headers=new_headers, body=body)


def start_viser(host: str, port: int, guard: Guard):
    """``viser.ViserServer(host, port)`` with ``guard`` checking every request (see module docstring)."""
    import viser
    import websockets.asyncio.server as ws_server

    check_bindable(host, port)
    used = []
    with _PATCH_LOCK:
        original = ws_server.serve

        class GuardedServe(original):  # type: ignore[misc, valid-type]
            def __init__(self, handler, *args, process_request=None, **kwargs):
                inner = process_request

                def checked(connection, request):
                    refused = guard.process_request(connection, request)
                    if refused is not None:
                        return refused
                    response = inner(connection, request) if inner is not None else None
                    return page_with_keys(request, response)

                used.append(True)
                super().__init__(handler, *args, process_request=checked, **kwargs)

        ws_server.serve = GuardedServe
        try:
            # viser prints its own banner with a token-less URL: the workbench prints the real one instead
            with contextlib.redirect_stdout(io.StringIO()):
                server = viser.ViserServer(host=host, port=port, verbose=False)
        finally:
            ws_server.serve = original
    if not used:
        server.stop()
        raise HandshakeGuardMissing("viser did not start its server through websockets.asyncio.server.serve: "
                                    "the workbench's Host/Origin check could not be installed (viser changed?)")
    return server
