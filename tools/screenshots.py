"""Screenshots of each workbench view for the README (docs/screenshots/*.png).

    python -m tools.screenshots [--out docs/screenshots]

Drives a real workbench server with headless Chromium: teleop on the default obstacle scene
(curvature colours, material frames, contacts), a shipped policy (if any) with its plots, and a
recorded session opened for replay.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tools.browser import WAIT_MS, close_toasts, expand_folder, launch, open_page, wait_for
from workbench.serve import default_scene
from workbench.session import policy_task, shipped_policies


def _shot(page, path: Path) -> None:
    close_toasts(page)
    time.sleep(0.5)
    path.write_bytes(page.screenshot(timeout=WAIT_MS))
    print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.screenshots", description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(Path("docs") / "screenshots"),
                    help="output folder (default docs/screenshots of the working directory: the checkout root)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    from playwright.sync_api import sync_playwright

    from workbench.serve import WorkbenchApp
    from workbench.session import Workbench

    rec_dir = Path(tempfile.mkdtemp(prefix="rodlab_shots_"))
    scene = default_scene()
    wb = Workbench.from_path(scene) if scene else Workbench.builtin()
    app = WorkbenchApp(wb, port=0, env_map=False, recordings_dir=rec_dir).start()
    with sync_playwright() as pw:
        browser = launch(pw)
        page = open_page(browser, app, width=1400, height=860)
        try:
            # 1. teleop on the default scene: bend towards the +x bar, frames + contacts shown
            wb.start_recording(rec_dir / "session.rrd")
            app.controls.sliders[2][0].value = -1.2
            app.controls.sliders[3][1].value = 0.6
            app.controls.frames.value = True
            app.controls.color_by.value = "κ1"
            expand_folder(page, "Teleop", "Zero sliders")
            wait_for(lambda: wb.frame_index > 60, timeout=120, what="rod to settle")
            _shot(page, out / "workbench_teleop.png")
            expand_folder(page, "Display", "top")
            _shot(page, out / "workbench_display.png")
            app.controls.frames.value = False
            expand_folder(page, "Obstacles", "Add obstacle")
            _shot(page, out / "workbench_obstacles.png")
            wb.stop_recording()
            # 2. a shipped policy with its live reward and plots
            files = shipped_policies()
            if files:
                app.policy.start_task(_task_of(files[0]), str(files[0]))
                expand_folder(page, "Policy", "Run policy")
                expand_folder(page, "Plots", ".uplot")
                wait_for(lambda: wb.policy.scalars.get("episode_step", 0) >= 20, timeout=180, what="policy steps")
                _shot(page, out / "workbench_policy.png")
                wb.stop_policy()
            else:
                print("no shipped policy yet: skipped workbench_policy.png")
            # 3. the recorded session, scrubbed to its middle
            app.replay.refresh_list()
            expand_folder(page, "Recordings", "Open recording")
            s = app.replay.open(rec_dir / "session.rrd")
            app.replay.timeline.value = int(0.6 * s.length)
            expand_folder(page, "Plots", ".uplot")
            wait_for(lambda: wb.replay.index == int(0.6 * s.length), what="scrub")
            _shot(page, out / "workbench_replay.png")
        finally:
            page.close()
            browser.close()
            app.stop()
    return 0


def _task_of(path: Path) -> str:
    return policy_task(path) or "follow_target"


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    sys.exit(main())
