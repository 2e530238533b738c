"""A recorded session of several rods replays as several rods: the live two-rod scene recorded to a real .rrd keeps
its rod layout, the replayed tube, the ghost and the exports (HTML payload and page, PNG) split at the joint, and the
material-frame overlay draws no frame on the joint edge, live or replayed. A recording without a layout is one rod."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from policies.recording import export as X
from sim.geometry import quat_to_matrix
from tools.browser import WAIT_MS
from workbench.session.frame import joint_edges, rod_edges
from workbench.view.tube import SIDES, vertex_count

ROOT = Path(__file__).resolve().parents[3]
SCENES = ROOT / "assets" / "scenes"
EXAMPLES = ROOT / "recordings" / "examples"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """(workbench on two_rods.toml after a recorded stretch, the recording's path)."""
    from workbench.session.core import Workbench

    wb = Workbench.from_path(SCENES / "two_rods.toml")
    path = wb.start_recording(tmp_path_factory.mktemp("rec") / "two_rods.rrd")
    for _ in range(6):
        wb.step()
    assert wb.stop_recording() == path
    return wb, path


@pytest.fixture
def server():
    import viser

    s = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield s
    s.stop()


def test_frame_edge_helpers():
    off = np.array([0, 5, 9, 12])
    np.testing.assert_array_equal(joint_edges(off), [4, 8])
    np.testing.assert_array_equal(joint_edges(None), [])
    np.testing.assert_array_equal(joint_edges([0, 12]), [])
    assert rod_edges(12, off).tolist() == [0, 1, 2, 3, 5, 6, 7, 9, 10]
    assert rod_edges(12).tolist() == list(range(11))


def test_recorded_session_keeps_the_rod_layout(recorded):
    from workbench.session.replay import ReplaySession

    wb, path = recorded
    model = wb.live.model
    s = ReplaySession.open(path)
    ep = s.ep
    np.testing.assert_array_equal(ep.scene.rod_node_offsets, model.rod_node_offsets)
    assert ep.scene.rod_names == ("base", "cross") == tuple(model.rod_names)
    fr = s.frame()
    np.testing.assert_array_equal(fr.rod_offsets, [0, 21, 42])
    assert fr.node_curvature[[20, 21]].tolist() == [0.0, 0.0]  # rod ends: the joint edge bends nothing


def test_replayed_frame_draws_two_tubes_and_no_frame_on_the_joint(recorded, server):
    from workbench.session.replay import ReplaySession
    from workbench.view.scene import SceneView

    wb, path = recorded
    s = ReplaySession.open(path)
    s.seek(s.length - 1)
    view = SceneView(server, 42, env_map=False)
    try:
        view.overlays.frames = True
        for fr in (s.frame(), wb.live.frame()):  # replayed, then live
            assert fr.m1 is not None and len(fr.m1) == 41
            view.render(fr, boundary=False)
            view.flush()
            mesh = view.rod.last_mesh
            assert len(mesh.vertices) == 2 * vertex_count(21, SIDES)  # one capped tube per rod
            split = vertex_count(21, SIDES)
            assert not ((mesh.faces < split).any(axis=1) & (mesh.faces >= split).any(axis=1)).any()
            pos = np.asarray(view.frames.batched_positions, np.float64)
            x = np.asarray(fr.node_pos, np.float64)
            assert pos.shape == (40, 3) and view.frames.visible  # 41 edges, less the joint
            joint_mid = 0.5 * (x[20] + x[21])
            assert np.linalg.norm(pos - joint_mid, axis=1).min() > 1e-3
            np.testing.assert_allclose(pos[20], 0.5 * (x[21] + x[22]), atol=1e-5)  # the cross rod's first edge
            R = quat_to_matrix(np.asarray(view.frames.batched_wxyzs, np.float64)[20])
            np.testing.assert_allclose(R[:, 0], fr.m1[21], atol=1e-3)
    finally:
        view.rod.tube.close()


def test_ghost_of_two_rods_has_no_segment_on_the_joint(recorded, server):
    from workbench.session.compare import Ghost, GhostView
    from workbench.session.replay import read_episodes

    _wb, path = recorded
    ep = read_episodes(path)[0]
    v = GhostView(server, Ghost(ep))
    v.draw(float(ep.sim_time[-1]))
    x = np.asarray(ep.positions[-1], np.float64)
    pos = np.asarray(v.rod.batched_positions, np.float64)
    assert pos.shape == (40, 3)
    assert np.linalg.norm(pos - 0.5 * (x[20] + x[21]), axis=1).min() > 1e-3
    np.testing.assert_allclose(np.asarray(v.rod.batched_scales)[:, 2],
                               np.linalg.norm(np.diff(x, axis=0), axis=1)[rod_edges(42, [0, 21, 42])], atol=1e-5)
    v.remove()


def test_an_old_recording_replays_as_one_rod(server):
    from workbench.session.compare import Ghost
    from workbench.session.replay import ReplaySession
    from workbench.view.scene import SceneView

    s = ReplaySession.open(EXAMPLES / "follow_target.rrd")
    fr = s.frame()
    n = len(fr.node_pos)
    assert fr.rod_offsets is None and X.pack_episode(s.ep)["rod_offsets"] == [0, n]
    assert len(Ghost(s.ep).edges()) == n - 1
    view = SceneView(server, n, env_map=False)
    try:
        view.overlays.frames = True
        view.render(fr, boundary=False)
        view.flush()
        assert len(view.rod.last_mesh.vertices) == vertex_count(n, SIDES)
        if fr.m1 is not None:
            assert len(view.frames.batched_positions) == n - 1
    finally:
        view.rod.tube.close()


def _two_rod_episode():
    """Two straight rods in the x-z plane, (0..1, 0, 0) and (0..1, 0, 1): the joint edge crosses the middle."""
    from policies.recording.schema import EpisodeData, StaticScene

    s, n = 3, 5
    pos = np.zeros((s, 2 * n, 3), np.float32)
    pos[:, :n, 0] = pos[:, n:, 0] = np.linspace(0.0, 1.0, n)
    pos[:, n:, 2] = 1.0
    scene = StaticScene(rod_radius=0.02, planar=True, rod_node_offsets=np.array([0, n, 2 * n]),
                        rod_names=("a", "b"))
    return EpisodeData(meta={"task": "two"}, scene=scene, control_step=np.arange(s), sim_time=np.arange(s) * 0.1,
                       positions=pos)


def test_png_draws_no_line_on_the_joint():
    from matplotlib.lines import Line2D

    from policies.recording.export_image import _figure, _view_basis

    ep = _two_rod_episode()
    r, u = _view_basis(True)
    x = np.asarray(ep.positions[0], np.float64)
    fig = _figure(ep, 0, 400, 300)
    segs = [ln for ln in fig.axes[0].get_children() if isinstance(ln, Line2D) and len(ln.get_xdata()) == 2
            and ln.get_linewidth() >= 3.0]
    ends = [tuple(np.round(np.c_[ln.get_xdata(), ln.get_ydata()].ravel(), 9)) for ln in segs]
    joint = tuple(np.round(np.array([x[4] @ r, x[5] @ r, x[4] @ u, x[5] @ u])[[0, 2, 1, 3]], 9))
    assert len(segs) == 8 and joint not in ends  # 4 segments per rod, none from one rod to the other
    d = X.unpack_html(X.episode_html(ep))
    assert d["rod_offsets"] == [0, 5, 10]


@pytest.mark.browser
def test_html_player_draws_no_line_on_the_joint(browser, tmp_path):
    """The joint edge crosses the canvas centre (the middle of everything drawn, front view): no rod pixels there;
    the same episode packed as one rod draws them."""
    import dataclasses
    import io

    from PIL import Image

    def rod_pixels_at_centre(ep, name: str) -> int:
        out = X.export_html(ep, tmp_path / name)
        page = browser.new_page(viewport={"width": 600, "height": 500})
        try:
            page.goto(out.as_uri())
            page.wait_for_selector("body[data-ready='1']", timeout=WAIT_MS)
            a = np.asarray(Image.open(io.BytesIO(page.locator("#cv").screenshot())).convert("RGB"), dtype=int)
        finally:
            page.close()
        h, w = a.shape[:2]
        c = a[h // 2 - 6:h // 2 + 7, w // 2 - 6:w // 2 + 7]
        return int(((c[..., 2] - c[..., 0] > 60) & (c[..., 2] > 120)).sum())

    ep = _two_rod_episode()
    assert rod_pixels_at_centre(ep, "two.html") == 0
    one = dataclasses.replace(ep, scene=dataclasses.replace(ep.scene, rod_node_offsets=None, rod_names=()))
    assert rod_pixels_at_centre(one, "one.html") > 10
