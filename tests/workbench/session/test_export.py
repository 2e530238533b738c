"""``rodlab export``: the standalone HTML player and the PNG of a frame (policies/recording/export.py).

The browser test opens the exported page from file:// in headless Chromium with the network off and checks
that it draws the rod, that the rod moves along the timeline, and that no request leaves file://.
"""
from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest

from policies.recording import export as X
from policies.recording.export_image import export_gif, export_png
from rodlab_cli import main as rodlab
from tools.browser import WAIT_MS, wait_for

ROOT = Path(__file__).resolve().parents[3]
EXAMPLES = ROOT / "recordings" / "examples"
REC = EXAMPLES / "tight_obstacles_2d.rrd"


@pytest.fixture(scope="module")
def episode():
    return X.load_episode(REC, 0)


def test_packing_round_trip_is_float32_exact(episode):
    page = X.episode_html(episode)
    d = X.unpack_html(page)
    assert d["n_frames"] == episode.steps and d["n_nodes"] == episode.positions.shape[1]
    np.testing.assert_array_equal(d["positions"], episode.positions.astype(np.float32))
    np.testing.assert_array_equal(d["target"], episode.target_pos.astype(np.float32))
    np.testing.assert_allclose(d["time"], episode.sim_time)
    assert len(d["obstacles"]["capsules"]) == len(episode.scene.capsules)
    assert d["planar"] is True


def test_decimation_keeps_first_and_last_frame(episode):
    d = X.unpack_html(X.episode_html(episode, max_frames=10))
    assert d["n_frames"] == 10 and d["frame_index"][0] == 0 and d["frame_index"][-1] == episode.steps - 1
    np.testing.assert_array_equal(d["positions"], episode.positions[d["frame_index"]])


def test_page_is_self_contained_and_escapes_recorded_strings(episode):
    ep = episode
    ep_meta = dict(ep.meta)
    try:
        ep.meta["policy"] = "</script><script>alert(1)</script>"
        page = X.episode_html(ep)
    finally:
        ep.meta.clear()
        ep.meta.update(ep_meta)
    assert page.count("</script>") == 2  # the data block and the player: nothing injected
    assert X.unpack_html(page)["meta"]["policy"] == "</script><script>alert(1)</script>"
    for ref in ("http://", "https://", "src=", "href=", "@import", "fetch(", "XMLHttpRequest"):
        assert ref not in page, ref


def test_cli_writes_html_and_png_atomically(tmp_path, capsys):
    html, png = tmp_path / "ep.html", tmp_path / "ep.png"
    assert rodlab(["export", str(REC), "--episode", "0", "--html", str(html), "--png", str(png),
                   "--frame", "10"]) == 0
    assert X.unpack_html(html.read_text())["n_frames"] == 52
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png.read_bytes())).convert("RGB"))
    assert img.shape[2] == 3 and (img.min(axis=2) < 200).mean() > 0.01  # something drawn on white
    assert oct(os.stat(html).st_mode & 0o777) == oct(0o666 & ~_umask())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep.html", "ep.png"]  # no temporary left


@pytest.mark.parametrize("rec", sorted(EXAMPLES.glob("*.rrd")), ids=lambda p: p.stem)
def test_every_example_recording_exports(rec, tmp_path):
    ep = X.load_episode(rec, 0)
    html = X.export_to_folder(ep, tmp_path, rec.stem)
    png = X.export_to_folder(ep, tmp_path, rec.stem, frame=ep.steps - 1)
    assert html == tmp_path / f"{rec.stem}.html" and png == tmp_path / f"{rec.stem}_f{ep.steps - 1}.png"
    d = X.unpack_html(html.read_text())
    np.testing.assert_array_equal(d["positions"], ep.positions)
    assert d["planar"] == ep.scene.planar and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("stem", ["../evil", "a/b", "", ".hidden"])
def test_export_to_folder_refuses_paths_outside_the_folder(episode, tmp_path, stem):
    with pytest.raises(X.ExportError, match="plain file name"):
        X.export_to_folder(episode, tmp_path, stem)


def _umask() -> int:
    old = os.umask(0o022)
    os.umask(old)
    return old


@pytest.mark.parametrize("args, msg", [
    (["--episode", "3"], "episode 3 out of range: the file has 1 episode (0..0)"),
    (["--episode", "-1"], "episode -1 out of range"),
    (["--png", "{out}/x.png", "--frame", "52"], "frame 52 out of range: the episode has 52 frames"),
    (["--html", "{out}/x.txt"], "must end in .html"),
    (["--gif", "{out}/x.png"], "must end in .gif"),
    (["--html", "{out}/no/such/x.html"], "does not exist"),
])
def test_cli_bad_requests_are_clear_errors(tmp_path, capsys, args, msg):
    args = [a.replace("{out}", str(tmp_path)) for a in args]
    if not {"--html", "--png", "--gif"} & set(args):
        args += ["--html", str(tmp_path / "x.html")]
    assert rodlab(["export", str(REC), *args]) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_cli_missing_and_corrupt_recording(tmp_path, capsys):
    out = tmp_path / "x.html"
    assert rodlab(["export", str(tmp_path / "none.rrd"), "--html", str(out)]) == 2
    assert "no such recording file" in capsys.readouterr().err
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(REC.read_bytes()[:5000])
    assert rodlab(["export", str(bad), "--html", str(out)]) == 2
    err = capsys.readouterr().err
    assert "rodlab export:" in err and "Traceback" not in err
    assert not out.exists()


def _shapes_episode():
    """A small synthetic episode with every obstacle kind (sphere, rotated box, mesh, capsule)."""
    from policies.recording.schema import EpisodeData, StaticScene

    s, n = 5, 11
    x = np.linspace(0, 1, n)
    pos = np.zeros((s, n, 3), np.float32)
    for k in range(s):
        pos[k, :, 0], pos[k, :, 2] = x, 0.3 * k / s * x ** 2
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * 0.2 + [0.5, 0.3, 0.2]
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    scene = StaticScene(sphere_centers=np.array([[0.5, 0.0, 0.4]]), sphere_radii=np.array([0.1]),
                        box_centers=np.array([[0.8, 0.0, 0.0]]), box_half_sizes=np.array([[0.1, 0.2, 0.05]]),
                        box_quats=np.array([[0.0, 0.0, np.sin(0.3), np.cos(0.3)]]), meshes=((verts, faces),),
                        capsules=np.array([[[0.2, -0.3, 0.1], [0.2, 0.3, 0.1]]]), capsule_radii=np.array([0.05]))
    return EpisodeData(meta={"task": "shapes"}, scene=scene, control_step=np.arange(s),
                       sim_time=np.arange(s) * 0.1, positions=pos)


def test_every_obstacle_kind_is_packed_and_drawn_in_the_png(tmp_path):
    ep = _shapes_episode()
    d = X.unpack_html(X.episode_html(ep))
    ob = d["obstacles"]
    assert [len(ob[k]) for k in ("capsules", "spheres", "boxes", "meshes")] == [1, 1, 1, 1]
    assert sorted(map(tuple, np.reshape(ob["meshes"][0]["e"], (-1, 2)))) == \
        [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    assert d["target"] is None and d["series"] == {}
    png = export_png(ep, 4, tmp_path / "s.png")
    assert png.stat().st_size > 1000


def test_gif_has_every_frame_and_the_rod_moves(episode, tmp_path):
    from PIL import Image

    out = export_gif(episode, tmp_path / "ep.gif", width=320, height=240, speed=2.0)
    with Image.open(out) as im:
        assert im.n_frames == episode.steps
        im.seek(0)
        first = _rod_pixels_rgb(np.asarray(im.convert("RGB")))
        assert im.info["duration"] == 250  # 0.5 s control step at 2x
        im.seek(im.n_frames - 1)
        last = _rod_pixels_rgb(np.asarray(im.convert("RGB")))
    assert first.sum() > 100 and last.sum() > 100
    assert (first ^ last).sum() > 0.3 * max(first.sum(), last.sum())
    with pytest.raises(X.ExportError, match="speed must be a positive number"):
        export_gif(episode, tmp_path / "x.gif", speed=0.0)


def test_nan_positions_are_refused():
    ep = _shapes_episode()
    ep.positions[2, 3, 1] = np.nan
    with pytest.raises(X.ExportError, match="NaN"):
        X.episode_html(ep)


def _rod_pixels(png: bytes) -> np.ndarray:
    """Mask of the rod's blue pixels in a screenshot (the rod is the only saturated blue drawn)."""
    from PIL import Image

    return _rod_pixels_rgb(np.asarray(Image.open(io.BytesIO(png)).convert("RGB")))


def _rod_pixels_rgb(a: np.ndarray) -> np.ndarray:
    a = a.astype(int)
    r, b = a[..., 0], a[..., 2]
    return (b - r > 60) & (b > 120)


@pytest.mark.browser
def test_html_opens_from_file_offline_and_rod_moves(browser, tmp_path):
    out = tmp_path / "episode.html"
    assert rodlab(["export", str(EXAMPLES / "random_obstacles_3d.rrd"), "--html", str(out)]) == 0
    ctx = browser.new_context(viewport={"width": 900, "height": 600}, offline=True)
    requests: list[str] = []
    ctx.on("request", lambda req: requests.append(req.url))
    ctx.route("**/*", lambda route: route.continue_() if route.request.url.startswith("file://")
              else route.abort())
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.goto(out.as_uri())
        page.wait_for_selector("body[data-ready='1']", timeout=WAIT_MS)
        canvas = page.locator("#cv")
        first = _rod_pixels(canvas.screenshot())
        assert first.sum() > 500, "rod not drawn on the canvas"
        slider = page.locator("#frame")
        slider.focus()
        slider.press("End")  # the timeline's last frame, as a user would
        page.wait_for_selector("body[data-frame='51']", timeout=WAIT_MS)
        last = _rod_pixels(canvas.screenshot())
        assert last.sum() > 500
        moved = (first ^ last).sum() / max(first.sum(), last.sum())
        assert moved > 0.3, f"rod barely moved between first and last frame ({moved:.2f})"
        assert "frame 51 / 51" in page.locator("#hud").inner_text()  # 0-based, as the page and the CLI count
        # play from the start: the frame advances by itself
        slider.press("Home")
        page.locator("#play").click()
        # polled from Python: the page's Content-Security-Policy forbids Playwright's evaluated predicates
        wait_for(lambda: int(page.locator("body").get_attribute("data-frame")) > 3, 20, what="playback")
        page.locator("#play").click()
        assert page.locator("#play").inner_text() == "Play"
    finally:
        page.close()
        ctx.close()
    assert errors == []
    assert requests and all(u.startswith("file://") for u in requests), requests


@pytest.mark.browser
def test_html_with_every_obstacle_kind_renders_without_script_errors(browser, tmp_path):
    out = X.export_html(_shapes_episode(), tmp_path / "shapes.html")
    page = browser.new_page(viewport={"width": 700, "height": 500})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.goto(out.as_uri())
        page.wait_for_selector("body[data-ready='1']", timeout=WAIT_MS)
        for view in ("top", "side", "front", "iso"):
            page.locator(f"#v-{view}").click()
        page.keyboard.press("ArrowRight")
        assert page.locator("body").get_attribute("data-frame") == "1"
        assert _rod_pixels(page.locator("#cv").screenshot()).sum() > 200
    finally:
        page.close()
    assert errors == []
