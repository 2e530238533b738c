"""Camera presets fitted to the scene (workbench.view.scene.fit_camera): each preset frames the rod, its targets and
obstacles whatever their size and place, from the preset's direction."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.session.core import Workbench
from workbench.view.scene import CAMERAS, FOV_Y, fit_camera

SCENES = Path(__file__).resolve().parents[3] / "assets" / "scenes"


def _half_angles(pos, look, pts) -> np.ndarray:
    """Angle of each point off the camera's axis [rad]."""
    axis = np.asarray(look) - np.asarray(pos)
    rel = np.asarray(pts) - np.asarray(pos)
    cos = rel @ axis / (np.linalg.norm(rel, axis=1) * np.linalg.norm(axis))
    return np.arccos(np.clip(cos, -1.0, 1.0))


@pytest.mark.parametrize("scene", ["arm.toml", "two_rods.toml", "cantilever_gravity.toml", "strip_tip_load.toml",
                                   "tight_obstacles_2d.toml"])
def test_every_preset_frames_the_rod_and_its_obstacles(scene):
    wb = Workbench.from_path(SCENES / scene)
    x = wb.frame().node_pos
    for preset, direction in CAMERAS.items():
        pos, look = fit_camera(preset, x)
        off = _half_angles(pos, look, x)
        assert off.max() < 0.5 * FOV_Y, f"{scene}: {preset} leaves a node {np.degrees(off.max()):.1f}° off axis"
        # from the preset's side, looking at the middle of the rod's box
        d = np.asarray(pos) - np.asarray(look)
        np.testing.assert_allclose(d / np.linalg.norm(d), np.asarray(direction) / np.linalg.norm(direction), atol=1e-12)
        np.testing.assert_allclose(look, 0.5 * (x.min(axis=0) + x.max(axis=0)), atol=1e-12)
        # and not from far away: seen obliquely (no straight rod end-on), its box spans half of the field of view
        if preset == "iso":
            lo, hi = x.min(axis=0), x.max(axis=0)
            corners = np.array([[a[0], b[1], c[2]] for a in (lo, hi) for b in (lo, hi) for c in (lo, hi)])
            assert _half_angles(pos, look, corners).max() > 0.25 * FOV_Y


def test_the_distance_follows_the_size_of_the_scene():
    small = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]])
    pa, la = fit_camera("iso", small)
    pb, lb = fit_camera("iso", 10.0 * small)
    assert np.linalg.norm(np.subtract(pb, lb)) == pytest.approx(10.0 * np.linalg.norm(np.subtract(pa, la)))
    # nothing finite to frame: a default view of a 1 m arm, not NaN
    assert np.isfinite(fit_camera("front", np.full((3, 3), np.nan))[0]).all()


def test_the_view_fits_the_drawn_scene_with_its_obstacles(tmp_path):
    from tests.workbench.conftest import make_app
    from workbench.session.obstacles import ObstacleEdit

    app = make_app(wait_for_browser=False, recordings_dir=tmp_path / "r", scenes_dir=tmp_path / "s")
    try:
        wb = app.wb
        assert app.view.camera[0] == "iso"  # the start view: fitted to the arm
        wb.add_obstacle(ObstacleEdit(kind="sphere", position=np.array([1.5, 0.0, 0.5]), radius=0.2))
        app.sync_obstacle_view()
        app.view.set_camera("front", frame=wb.frame())
        preset, pos, look = app.view.camera
        far = np.array([[1.7, 0.0, 0.5]])
        assert preset == "front" and _half_angles(pos, look, far).max() < 0.5 * FOV_Y
        assert tuple(app.server.initial_camera.position) == pytest.approx(pos)  # pages opened later start there
    finally:
        app.stop()


class _Camera:
    def __init__(self, position, look_at):
        self.position, self.look_at = tuple(position), tuple(look_at)


class _Page:
    """A page's camera as the server sees it: what the page last reported."""

    def __init__(self, position, look_at):
        self.camera = _Camera(position, look_at)


def test_follow_keeps_its_offset_through_mixed_reports_and_takes_the_users(monkeypatch):
    """Following the tip keeps the camera's offset from the look-at: a report that mixes the position of one placed
    camera with the look-at of a later one (the page reports on its own schedule) does not change it; a camera the user
    moved gives the new offset; after following stops, the camera is read afresh."""
    import types

    from workbench.view.scene import SceneView

    page = _Page((1.0, 0.0, 1.0), (0.0, 0.0, 0.0))
    sent = []

    class _Server:
        def get_clients(self):
            return {7: page}

    view = types.SimpleNamespace(server=_Server(), _following={})
    monkeypatch.setattr("workbench.view.scene.place_camera",
                        lambda client, pos, look: sent.append((np.asarray(pos), np.asarray(look))))
    follow = SceneView.follow.__get__(view)
    follow((0.0, 0.0, 0.5))
    np.testing.assert_allclose(sent[-1][0], (1.0, 0.0, 1.5))
    page.camera = _Camera((1.0, 0.0, 1.0), (0.0, 0.0, 0.5))  # old position, new look-at
    follow((0.0, 0.0, 0.6))
    np.testing.assert_allclose(sent[-1][0], (1.0, 0.0, 1.6))  # the offset kept (not (1, 0, 0.5))
    page.camera = _Camera((0.0, 1.0, 1.6), (0.0, 0.0, 0.6))  # the user orbited about the tip
    follow((0.0, 0.0, 0.7))
    np.testing.assert_allclose(sent[-1][0], (0.0, 1.0, 1.7))
    np.testing.assert_allclose(sent[-1][1], (0.0, 0.0, 0.7))
    SceneView.unfollow(view)
    page.camera = _Camera((2.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    follow((0.0, 0.0, 0.0))
    assert len(sent) == 3  # already looking at the tip from its own offset: nothing placed
    page_gone = {}
    view.server.get_clients = lambda: page_gone  # the page closed while following: its camera is forgotten
    follow((0.0, 0.0, 0.1))
    assert view._following == {}
