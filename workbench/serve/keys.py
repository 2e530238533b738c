"""Keyboard shortcuts of the workbench page: space = play / pause, → = one step, r = reset, [ / ] = previous / next
event. With a recording open, space plays and pauses the replay and → steps it one frame.

viser has no key events for the server. The workbench adds a small static script to the page it serves
(``workbench.serve.handshake`` inserts it into viser's ``index.html``); on a key press outside text fields the script
clicks the page's own "Playing" checkbox, "Step" button or "Reset" button. The server sees the same GUI messages as
for a mouse click and checks them the same way; the script sends nothing of its own and adds no endpoint.

→ is taken from viser's keyboard camera (which turns the view with the arrow keys); ←, ↑, ↓ still turn it.
"""
from __future__ import annotations

import gzip

#: key (``KeyboardEvent.key``) -> (kind, label) of the control it operates
SHORTCUTS = {" ": ("checkbox", "Playing"), "ArrowRight": ("button", "Step"), "r": ("button", "Reset"),
             "[": ("button", "Previous event"), "]": ("button", "Next event")}

SCRIPT = """<script data-rodlab="keys">(() => {
  const shortcuts = %(shortcuts)s;
  const typing = (el) => {
    if (!el || !el.tagName) return false;
    if (el.isContentEditable) return true;
    const tag = el.tagName.toLowerCase();
    if (tag === "textarea" || tag === "select") return true;
    if (tag === "input") return !["checkbox", "radio", "button", "submit", "reset"].includes((el.type || "").toLowerCase());
    const role = (el.getAttribute && el.getAttribute("role")) || "";
    return ["slider", "combobox", "textbox", "spinbutton", "listbox", "option"].includes(role);
  };
  const control = (kind, label) => {
    if (kind === "button") {
      return [...document.querySelectorAll("button")].find((b) => b.textContent.trim() === label) || null;
    }
    for (const lab of document.querySelectorAll("label")) {
      if (lab.textContent.trim() === label && lab.control) return lab.control;
    }
    return null;
  };
  const onKey = (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey || typing(e.target) || typing(document.activeElement)) return;
    const key = e.key === "R" ? "r" : e.key;
    const what = shortcuts[key];
    if (!what) return;
    e.preventDefault();
    e.stopImmediatePropagation();
    if (e.type !== "keydown" || e.repeat) return;
    const el = control(what[0], what[1]);
    if (el && !el.disabled) el.click();
  };
  window.addEventListener("keydown", onKey, true);
  window.addEventListener("keyup", onKey, true);
})();</script>"""


def script() -> str:
    import json

    return SCRIPT % {"shortcuts": json.dumps({k: list(v) for k, v in SHORTCUTS.items()})}


_cache: dict[tuple[int, bool], tuple[bytes, bytes]] = {}


def with_keys(body: bytes, gzipped: bool) -> bytes:
    """viser's page ``body`` (gzip-compressed or not) with the shortcut script added at the end of its <body>."""
    key = (id(body), gzipped)
    hit = _cache.get(key)
    if hit is not None and hit[0] is body:
        return hit[1]
    html = gzip.decompress(body) if gzipped else body
    tag = script().encode()
    at = html.rfind(b"</body>")
    html = html[:at] + tag + html[at:] if at >= 0 else html + tag
    out = gzip.compress(html) if gzipped else html
    _cache[key] = (body, out)
    return out
