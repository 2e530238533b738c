"""Frame-rate benchmark of single-env teleop with a headless browser attached.

    python -m tools.fps_bench [--seconds 10] [SCENE.toml] [--no-browser]

The sim thread runs as fast as it can (``speed=inf``): every frame is one sim step of the live rod
plus one full scene update (tube, frames, contacts) pushed over the websocket to the page, which
renders it with WebGL (SwiftShader on machines without a GPU). The rod is driven in delta mode so
every frame changes. Prints frames/s, the mean sim step time, and the browser's own animation
frame rate. In normal use the thread is paced to real time (one step per ``dt`` of wall clock).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.fps_bench", description=__doc__.split("\n")[0])
    ap.add_argument("scene", nargs="?", help="scene TOML (default: the workbench default scene)")
    ap.add_argument("--seconds", type=float, default=10.0, help="measurement window [s] (default 10)")
    ap.add_argument("--warmup", type=float, default=3.0, help="seconds before measuring (default 3)")
    ap.add_argument("--no-browser", action="store_true", help="measure without a page attached")
    ap.add_argument("--frames", action="store_true", help="also draw the material frames overlay")
    ap.add_argument("--max-fps", type=float, default=60.0, help="scene updates per second at most (default 60)")
    ap.add_argument("--size", default="1280x800", help="browser viewport WxH (default 1280x800)")
    args = ap.parse_args(argv)

    from workbench.app import WorkbenchApp
    from workbench.cli import default_scene
    from workbench.core import Workbench

    scene = Path(args.scene) if args.scene else default_scene()
    wb = Workbench.from_path(scene) if scene else Workbench.builtin()
    wb.set_teleop_mode("delta")
    wb.set_teleop_value(2, 0, 0.4)  # keep the rod moving: every frame differs
    wb.set_teleop_value(3, 1, -0.3)
    app = WorkbenchApp(wb, port=0, env_map=False, speed=float("inf"))
    app.thread.max_fps = args.max_fps
    width, height = (int(v) for v in args.size.lower().split("x"))
    app.view.overlays.frames = args.frames
    pw = browser = page = None
    try:
        if not args.no_browser:
            from playwright.sync_api import sync_playwright

            from tools.browser import launch, open_page

            pw = sync_playwright().start()
            browser = launch(pw)
        wb.set_playing(False)
        app.start()
        if browser is not None:
            page = open_page(browser, app, width=width, height=height)
        wb.set_playing(True)
        time.sleep(args.warmup)
        th = app.thread
        f0, s0, t0 = th.frames, wb.frame_index, time.perf_counter()
        raf0 = page.evaluate("() => { window.__raf = 0; const f = () => { window.__raf++; "
                             "requestAnimationFrame(f); }; requestAnimationFrame(f); return 0; }") if page else 0
        step_ms = []
        t_end = t0 + args.seconds
        while time.perf_counter() < t_end:
            time.sleep(0.1)
            step_ms.append(th.step_ms)
        dt = time.perf_counter() - t0
        frames = th.frames - f0
        raf = (page.evaluate("() => window.__raf") - raf0) if page else 0
        print(f"scene: {scene or 'built-in arm'}  browser: {'headless Chromium' if page else 'none'}  "
              f"window: {dt:.1f} s")
        print(f"frames/s (sim step + scene update pushed): {frames / dt:.1f}")
        print(f"sim steps/s: {(wb.frame_index - s0) / dt:.1f}   mean sim step: "
              f"{sum(step_ms) / max(len(step_ms), 1):.2f} ms   real-time factor: {(wb.frame_index - s0) * wb.live.dt / dt:.1f}")
        if page:
            print(f"browser animation frames/s: {raf / dt:.1f}")
        if th.error is not None:
            print(f"sim thread error: {th.error}", file=sys.stderr)
            return 1
    finally:
        if page is not None:
            page.close()
        if browser is not None:
            browser.close()
        if pw is not None:
            pw.stop()
        app.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
