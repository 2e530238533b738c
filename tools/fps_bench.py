"""Frame-rate benchmark of the workbench with a real headless Chromium attached: one env (teleop) and a grid of
N envs of a task under its shipped policy (``workbench.session.grid``).

    python -m tools.fps_bench [--envs 1,16] [--seconds 10] [--json docs/bench/workbench_fps.json] [SCENE.toml]

One env: the sim thread runs as fast as it can (``speed=inf``), the rod driven in delta mode so every frame changes;
every frame is one sim step plus one full scene update (tube, frames, contacts) pushed over the websocket. Grid: the
N envs step control step after control step as fast as they can, each redraw one batched update of all rods.
Scene updates are capped at ``--max-fps`` per second (the workbench's default 60 for one env, 30 for the grid).

Figures per configuration: scene updates pushed by the server per second, websocket messages and megabytes the page
received per second (what was delivered), the page's own animation frames per second (headless Chromium renders
with software WebGL), sim (control) steps per second. ``--json`` writes them (atomically) for BENCHMARKS.md §4.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from sim.support import atomicio
from tools.browser import close_toasts, launch, newest_client, wait_for
from workbench.serve import default_scene

RAF_JS = ("() => { window.__raf = 0; const f = () => { window.__raf++; requestAnimationFrame(f); }; "
          "requestAnimationFrame(f); return 0; }")


def _open_page(browser, app, width: int, height: int, counter: dict):
    """The workbench page, counting the websocket messages (and bytes) it receives."""
    page = browser.new_page(viewport={"width": width, "height": height})

    def on_ws(ws) -> None:
        def got(payload) -> None:
            counter["messages"] += 1
            counter["bytes"] += len(payload)

        ws.on("framereceived", got)

    page.on("websocket", on_ws)
    n0 = len(app.server.get_clients())
    page.goto(app.url)
    page.get_by_text("Teleop", exact=True).first.wait_for(timeout=60000)
    wait_for(lambda: len(app.server.get_clients()) > n0, 30, what="browser client")
    client = newest_client(app)
    wait_for(lambda: client.camera.image_width > 0, 30, what="camera message")
    close_toasts(page)
    return page


def measure(args, n_envs: int, browser) -> dict:
    from workbench.serve import WorkbenchApp
    from workbench.session import Workbench

    scene = Path(args.scene) if args.scene else default_scene()
    wb = Workbench.from_path(scene) if scene else Workbench.builtin()
    wb.set_teleop_mode("delta")
    wb.set_teleop_value(2, 0, 0.4)  # keep the rod moving: every frame differs
    wb.set_teleop_value(3, 1, -0.3)
    app = WorkbenchApp(wb, port=0, env_map=False, speed=float("inf"), wait_for_browser=False)
    app.thread.max_fps = args.max_fps
    width, height = (int(v) for v in args.size.lower().split("x"))
    page = None
    counter = {"messages": 0, "bytes": 0}
    try:
        wb.set_playing(False)
        app.start()
        if browser is not None:
            page = _open_page(browser, app, width, height, counter)
        if n_envs == 1:
            wb.set_playing(True)

            def frames() -> int:
                return app.thread.frames

            def steps() -> int:
                return wb.frame_index
        else:
            from workbench.session import shipped_policies

            pol = shipped_policies(args.task)
            app.grid.start(args.task, str(pol[0]) if pol else "zero", n_envs, speed=float("inf"),
                           max_fps=args.grid_max_fps)

            def frames() -> int:
                return app.grid.runner.frames

            def steps() -> int:
                return app.grid.session.steps
        time.sleep(args.warmup)
        f0, s0, m0, b0 = frames(), steps(), counter["messages"], counter["bytes"]
        raf0 = page.evaluate(RAF_JS) if page else 0
        t0 = time.perf_counter()
        time.sleep(args.seconds)
        dt = time.perf_counter() - t0
        out = {"envs": n_envs, "scene": str(scene or "built-in arm") if n_envs == 1 else args.task,
               "browser": "headless Chromium" if page else "none", "window_s": round(dt, 2),
               "frames_per_s": round((frames() - f0) / dt, 2),
               "steps_per_s": round((steps() - s0) / dt, 2),
               "ws_messages_per_s": round((counter["messages"] - m0) / dt, 2),
               "ws_mb_per_s": round((counter["bytes"] - b0) / dt / 1e6, 3),
               "browser_animation_frames_per_s": round((page.evaluate("() => window.__raf") - raf0) / dt, 2)
               if page else None,
               "steps": "sim steps" if n_envs == 1 else "control steps of all envs"}
        err = app.thread.error if n_envs == 1 else app.grid.runner.error
        if err is not None:
            raise RuntimeError(f"{n_envs} envs: {err}")
        return out
    finally:
        app.grid.stop()
        if page is not None:
            page.close()
        app.stop()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.fps_bench", description=__doc__.split("\n")[0])
    ap.add_argument("scene", nargs="?", help="scene TOML of the one-env run (default: the workbench default scene)")
    ap.add_argument("--envs", default="1,16", help="comma-separated env counts; 1 = teleop, N > 1 = grid (default 1,16)")
    ap.add_argument("--task", default="follow_target", help="task of the grid runs (default follow_target)")
    ap.add_argument("--seconds", type=float, default=10.0, help="measurement window [s] (default 10)")
    ap.add_argument("--warmup", type=float, default=3.0, help="seconds before measuring (default 3)")
    ap.add_argument("--no-browser", action="store_true", help="measure without a page attached")
    ap.add_argument("--max-fps", type=float, default=60.0, help="one env: scene updates per second at most (60)")
    ap.add_argument("--grid-max-fps", type=float, default=30.0, help="grid: redraws per second at most (30)")
    ap.add_argument("--size", default="1280x800", help="browser viewport WxH (default 1280x800)")
    ap.add_argument("--json", help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    try:
        counts = [int(v) for v in args.envs.split(",") if v.strip()]
    except ValueError:
        ap.error(f"--envs {args.envs!r}: give comma-separated integers, e.g. 1,16")
    from workbench.session import MAX_ENVS

    if not counts or any(not 1 <= n <= MAX_ENVS for n in counts):
        ap.error(f"--envs {args.envs!r}: each count must be in [1, {MAX_ENVS}]")
    pw = browser = None
    results = []
    try:
        if not args.no_browser:
            from playwright.sync_api import sync_playwright


            pw = sync_playwright().start()
            browser = launch(pw)
        for n in counts:
            r = measure(args, n, browser)
            results.append(r)
            print(f"{n:3d} env(s): {r['frames_per_s']:.1f} frames/s pushed · {r['ws_messages_per_s']:.1f} websocket "
                  f"messages/s ({r['ws_mb_per_s']:.2f} MB/s) received by the page · page animation frames/s "
                  f"{r['browser_animation_frames_per_s']} · {r['steps_per_s']:.1f} {r['steps']}/s")
    finally:
        if browser is not None:
            browser.close()
        if pw is not None:
            pw.stop()
    if args.json:

        doc = {"command": "python -m tools.fps_bench " + " ".join(argv if argv is not None else sys.argv[1:]),
               "seconds": args.seconds, "size": args.size, "results": results}
        atomicio.write_text(args.json, json.dumps(doc, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
