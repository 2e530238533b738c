"""Headless Chromium helpers (Playwright) shared by the browser tests, the screenshot script and
the frame-rate benchmark. Uses the system Chromium (never ``playwright install``).
"""
from __future__ import annotations

import os
import re
import shutil
import time
from typing import Callable

import numpy as np

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/lib/chromium/chromium", "/usr/bin/chromium-browser")
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


class ChromiumMissing(RuntimeError):
    pass


def chromium_path() -> str:
    """Path of the system Chromium; raises ChromiumMissing with the install hint."""
    env = os.environ.get("RODLAB_CHROMIUM")
    for p in ((env,) if env else ()) + CHROMIUM_CANDIDATES:
        if p and os.path.exists(p):
            return p
    found = shutil.which("chromium")
    if found:
        return found
    raise ChromiumMissing("Chromium not found (looked at /usr/bin/chromium): install it with "
                          "`make system-deps` (apt-get install -y chromium) (never `playwright install`)")


def launch(playwright):
    return playwright.chromium.launch(executable_path=chromium_path(), headless=True, args=CHROMIUM_ARGS)


# Waits end on a condition (the page's state, the server's counters), never on elapsed time. The bound only stops
# a hang, so that one broken test does not hold up the suite: 300 s is ten times the longest single wait seen with
# software WebGL beside two CPU hogs on two cores (RODLAB_WAIT_BOUND_S overrides it).
WAIT_BOUND_S = float(os.environ.get("RODLAB_WAIT_BOUND_S", "300"))
WAIT_MS = int(WAIT_BOUND_S * 1000)  # the same bound for Playwright's waits (milliseconds)


def poll(pred: Callable[[], bool], seconds: float, interval: float = 0.05) -> bool:
    """True as soon as ``pred()`` holds, False after ``seconds``: for a gesture to repeat, never a failure."""
    t_end = time.monotonic() + seconds
    while True:
        if pred():
            return True
        if time.monotonic() >= t_end:
            return False
        time.sleep(interval)


def wait_for(pred: Callable[[], bool], timeout: float | None = None, interval: float = 0.05,
             what: str | Callable[[], str] = "") -> None:
    """Wait until ``pred()`` holds. ``timeout`` is an outer bound against a hang and never shorter than
    :data:`WAIT_BOUND_S`, so a busy machine only makes the wait longer. ``what`` names the condition in the
    error; a callable is asked at the timeout (to report the state the wait ended in)."""
    bound = max(timeout or 0.0, WAIT_BOUND_S)
    if not poll(pred, bound, interval):
        told = what() if callable(what) else what
        raise TimeoutError(f"timed out after {bound:.0f} s waiting for {told or pred}")


def retry_until(action: Callable[[], None], pred: Callable[[], bool], *, attempt_s: float = 10.0,
                what: str | Callable[[], str] = "") -> None:
    """Repeat ``action()`` until ``pred()`` holds, each try given ``attempt_s`` to take effect (a click that a
    software-GL page had not drawn yet misses); fails after :data:`WAIT_BOUND_S`."""
    t_end = time.monotonic() + WAIT_BOUND_S
    while True:
        action()
        if poll(pred, attempt_s):
            return
        if time.monotonic() >= t_end:
            told = what() if callable(what) else what
            raise TimeoutError(f"timed out after {WAIT_BOUND_S:.0f} s repeating the gesture for {told or pred}")


def open_page(browser, app, *, width: int = 1280, height: int = 800):
    """Open the workbench page and wait until the GUI and the camera are known server-side."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.set_default_timeout(WAIT_MS)
    before = set(app.server.get_clients())
    page.goto(app.url)
    page.get_by_text("Teleop", exact=True).first.wait_for()
    wait_for(lambda: set(app.server.get_clients()) - before, what="browser client")
    client = newest_client(app)
    wait_for(lambda: client.camera.image_width > 0, what="camera message")
    close_toasts(page)
    return page


def newest_client(app):
    clients = app.server.get_clients()
    return clients[max(clients)]


def close_toasts(page) -> None:
    """Hide viser's notifications (e.g. the "Software WebGL rendering detected" toast)."""
    try:
        page.add_style_tag(content=".mantine-Notifications-root { display: none !important; }")
    except Exception:  # noqa: BLE001 - cosmetic
        pass


def wait_smooth(page, frames: int = 4, max_gap_ms: float = 400.0, timeout_ms: int = 15000) -> None:
    """Wait for ``frames`` consecutive animation frames spaced less than ``max_gap_ms``."""
    page.evaluate("""([n, gap, tmo]) => new Promise((res) => {
        let last = performance.now(), ok = 0; const t0 = last;
        function f(t) { if (t - last < gap) ok++; else ok = 0; last = t;
          if (ok >= n || t - t0 > tmo) res(ok); else requestAnimationFrame(f); }
        requestAnimationFrame(f); })""", [frames, max_gap_ms, timeout_ms])


def slider_root(page, label: str):
    lab = page.locator("label").filter(has_text=re.compile("^" + re.escape(label) + "$"))
    return page.locator(f'[id="{lab.first.get_attribute("for")}"]')


def slider_thumb(page, label: str):
    return slider_root(page, label).get_by_role("slider")


def project(cam, pts: np.ndarray, W: int, H: int) -> np.ndarray:
    """World points (K, 3) -> page pixels (K, 2) with viser's client camera (OpenCV convention)."""
    import viser.transforms as vtf

    R = vtf.SO3(np.asarray(cam.wxyz)).as_matrix()
    pc = (np.asarray(pts) - np.asarray(cam.position)) @ R
    f = (H / 2) / np.tan(cam.fov / 2)
    return np.stack([W / 2 + f * pc[:, 0] / pc[:, 2], H / 2 + f * pc[:, 1] / pc[:, 2]], 1)


def drag_gizmo_x(page, client, origin: np.ndarray, *, scale: float | None = None, dist: float = 0.2) -> None:
    """Drag a transform gizmo at ``origin`` along its +x arrow by roughly ``dist`` metres."""
    if scale is None:
        from workbench.view import GIZMO_SCALE as scale
    box = page.locator("canvas").first.bounding_box()
    W, H = box["width"], box["height"]
    a = origin + np.array([0.73 * scale, 0.0, 0.0])
    b = a + np.array([dist, 0.0, 0.0])
    uv = project(client.camera, np.stack([a, b]), W, H) + np.array([box["x"], box["y"]])
    page.mouse.move(*uv[0])
    page.mouse.down()
    page.mouse.move(*uv[1], steps=8)
    page.mouse.up()


def canvas_png(page) -> bytes:
    """Screenshot of the 3D canvas only."""
    return page.locator("canvas").first.screenshot(timeout=WAIT_MS)


def canvas_variance(page) -> float:
    return image_variance(canvas_png(page))


def image_diff_fraction(a: bytes, b: bytes, *, level: float = 30.0) -> float:
    """Fraction of pixels whose grey level differs by more than ``level`` between two PNGs."""
    import io

    from PIL import Image

    ia = np.asarray(Image.open(io.BytesIO(a)).convert("L"), dtype=np.float64)
    ib = np.asarray(Image.open(io.BytesIO(b)).convert("L"), dtype=np.float64)
    if ia.shape != ib.shape:
        return 1.0
    return float(np.mean(np.abs(ia - ib) > level))


def expand_folder(page, folder: str, probe: str) -> None:
    """Open a GUI tab or folder named ``folder`` unless ``probe`` (a button name, or a CSS selector starting with
    '.') inside it is already visible."""
    btn = page.locator(probe) if probe.startswith(".") else page.get_by_role("button", name=probe)
    if btn.count() and btn.first.is_visible():
        return
    page.get_by_text(folder, exact=True).first.click()
    btn.first.wait_for(state="visible", timeout=WAIT_MS)


def image_variance(png_bytes: bytes) -> float:
    """Pixel variance of a screenshot (0 = blank)."""
    import io

    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png_bytes)).convert("RGB"), dtype=np.float64)
    return float(img.var())
