"""Real browser: the replay plots show every recorded series (also one whose first sample is missing), with a
cursor at the timeline position; the live plots never join two episodes across a reset."""
from __future__ import annotations

import io

import numpy as np
import pytest
from playwright.sync_api import Error as PlaywrightError

from tools.browser import WAIT_MS, expand_folder, slider_thumb, wait_for
from workbench.session.plots import COLORS

pytestmark = pytest.mark.browser

CHARTS_JS = """() => Object.values(window.__viserTestpoints?.uplots ?? {}).map(({chart}) => ({
    title: chart.root.querySelector('.u-title')?.textContent ?? '',
    ymin: chart.scales.y.min, ymax: chart.scales.y.max, xmin: chart.scales.x.min, xmax: chart.scales.x.max,
    labels: chart.series.map(s => String(s.label)),
    data: chart.data.map(col => Array.from(col, v => (Number.isFinite(v) ? v : null))),
}))"""


def _charts(page) -> dict[str, dict]:
    return {c["title"]: c for c in page.evaluate(CHARTS_JS)}


def _color_pixels(png: bytes, hex_color: str, tol: int = 40) -> int:
    from PIL import Image

    a = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    rgb = np.array([int(hex_color[i:i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(a - rgb).max(axis=-1) < tol).sum())


def _write_recording(path, n: int = 40) -> None:
    from policies.recording import Recorder
    from policies.recording.schema import StaticScene

    rec = Recorder(path)
    rec.begin_episode({"task": "synthetic", "policy": "none"}, StaticScene(rod_radius=0.02))
    s = np.linspace(0.0, 1.0, 11)
    for k in range(n):
        x = np.stack([0.05 * k * s * s, np.zeros_like(s), s], 1)
        sc = {"tip_error": 0.3 - 0.005 * k, "energy/bend": 0.01 * k, "energy/kinetic": 0.2 - 0.004 * k}
        if k > 0:  # the first frame has no reward / solver / contact values yet (as in a real episode)
            sc.update({"reward": -1.0 + 0.02 * k, "reward_terms/distance": -0.5 + 0.01 * k,
                       "ori_error": 0.4 - 0.005 * k, "solver/newton_iters": float(2 + k % 3),
                       "contact/max_normal_force": 5.0 + k})
        rec.log_step(control_step=k, sim_time=0.01 * k, node_pos=x, scalars=sc)
    rec.end_episode()
    rec.close()


def test_replay_plots_every_series_with_timeline_cursor(wb_page):
    app, page = wb_page
    wb = app.wb
    _write_recording(app.recordings_dir / "plots.rrd")
    app.replay.refresh_list()
    expand_folder(page, "Recordings", "Open recording")
    app.replay.file.value = "plots.rrd"
    page.get_by_role("button", name="Open recording").click()
    wait_for(lambda: wb.mode == "replay" and wb.replay is not None, timeout=30, what="recording opened")
    expand_folder(page, "Plots", ".uplot")
    want = {"reward and its terms": ["reward", "distance"], "tip error [m]": ["tip_error"],
            "energies [J]": ["bend", "kinetic"], "max contact force [N]": ["max_normal_force"],
            "Newton iterations / substeps": ["newton_iters"]}
    wait_for(lambda: any(p.key == "ori_error" for p in app.plots.shown), what="the replay's plots on the server")
    want = {**want, next(p.title for p in app.plots.shown if p.key == "ori_error"): ["ori_error"]}
    wait_for(lambda: set(want) <= set(_charts(page)), timeout=30, what="every plot in the page")
    charts = _charts(page)
    for title, names in want.items():
        c = charts[title]
        assert c["ymin"] is not None and c["ymax"] is not None and c["ymin"] < c["ymax"], title
        for name in names:
            i = c["labels"].index(name)
            finite = [v for v in c["data"][i] if v is not None]
            assert len(finite) >= 39, (title, name)

        def lines_drawn(title=title, names=names) -> bool:  # ~ a plot width of pixels in each series' colour
            canvas = page.locator(".uplot").filter(has_text=title).locator("canvas").first
            try:
                png = canvas.screenshot(timeout=WAIT_MS)
            except PlaywrightError:  # the page replaced the plot's element meanwhile (a newer message): look again
                return False
            return all(_color_pixels(png, COLORS[j]) > 100 for j in range(len(names)))

        wait_for(lines_drawn, what=f"the lines of {title!r} drawn")
    # the timeline cursor follows the timeline slider
    def cursor_x() -> float | None:
        c = _charts(page)["tip error [m]"]
        i = c["labels"].index("timeline")
        xs = [x for x, v in zip(c["data"][0], c["data"][i]) if v is not None]
        return xs[0] if xs else None

    wait_for(lambda: cursor_x() == pytest.approx(0.0), what="cursor at the first frame")
    expand_folder(page, "Recordings", "Open recording")
    th = slider_thumb(page, "Timeline")
    th.focus()
    th.press("End")
    wait_for(lambda: wb.replay.index == wb.replay.length - 1, what="timeline at the end")
    wait_for(lambda: cursor_x() == pytest.approx(0.39), what="cursor at the last frame")


def test_live_plots_split_at_episode_reset(wb_page):
    app, page = wb_page
    wb = app.wb
    app.policy.start_task("follow_target", "zero")
    wait_for(lambda: wb.policy.scalars.get("episode_step", 0) >= 3, timeout=60, what="episode to advance")
    with wb.lock:
        wb.policy.done = True  # the next control step starts a new episode (sim time back to 0)
    wait_for(lambda: any("reward (prev. episode)" in p.labels for p in app.plots.shown), timeout=60,
             what="live plot with the previous episode")
    expand_folder(page, "Plots", ".uplot")

    def split_ok() -> bool:
        c = _charts(page).get("reward and its terms")
        if c is None or "reward (prev. episode)" not in c["labels"]:
            return False
        cur = c["data"][c["labels"].index("reward")]
        prev = c["data"][c["labels"].index("reward (prev. episode)")]
        i_cur = [i for i, v in enumerate(cur) if v is not None]
        i_prev = [i for i, v in enumerate(prev) if v is not None]
        # both drawn, never at the same sample, the previous episode entirely before the current one
        return bool(i_cur and i_prev) and max(i_prev) < min(i_cur)

    wait_for(split_ok, timeout=30, what="reward plot split into the two episodes in the page")

    def newest_shown(title: str) -> bool:  # the x axis moves along with the live data
        c = _charts(page).get(title)
        xs = c["data"][0] if c else []
        return bool(xs) and c["xmin"] <= xs[0] + 1e-9 and c["xmax"] >= xs[-1] - 1e-9

    x_last = max(_charts(page)["tip error [m]"]["data"][0])
    wait_for(lambda: max(_charts(page)["tip error [m]"]["data"][0]) > x_last + 1.0, timeout=60, what="a second more")
    for title in ("tip error [m]", "reward and its terms"):
        wait_for(lambda: newest_shown(title), timeout=15, what=f"{title}: newest samples inside the x axis")
