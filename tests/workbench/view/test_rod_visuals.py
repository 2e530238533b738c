"""The rod's tube mesh (workbench.view.tube) and the rod overlays (workbench.view.rod): geometry, normals, colours, GLB
packing, tip trail, tip frame, roll/pitch/yaw of the obstacle fields."""
from __future__ import annotations

import io
import types

import numpy as np
import pytest
import trimesh

from workbench.session.frame import Frame, quat_from_rpy_deg, rpy_deg_from_quat
from workbench.view.tube import glb_bytes, node_frames, tube_faces, tube_mesh, vertex_count

N, K, R = 21, 16, 0.02


def straight() -> np.ndarray:
    return np.stack([np.zeros(N), np.zeros(N), np.linspace(0.0, 1.0, N)], 1)


def sharp() -> np.ndarray:
    """A rod folded by 150° at its middle node (and one exactly folded back node at the end)."""
    s = np.linspace(0.0, 0.5, 11)
    a = np.stack([np.zeros(11), np.zeros(11), s], 1)
    d = np.array([np.sin(np.radians(150.0)), 0.0, np.cos(np.radians(150.0))])
    b = a[-1] + np.linspace(0.05, 0.5, 10)[:, None] * d
    return np.concatenate([a, b])


def material_m1(x: np.ndarray) -> np.ndarray:
    e = np.diff(x, axis=0)
    t = e / np.linalg.norm(e, axis=1, keepdims=True)
    m = np.cross(t, [0.0, 1.0, 0.0])
    return m / np.linalg.norm(m, axis=1, keepdims=True)


@pytest.mark.parametrize("shape", [straight, sharp])
@pytest.mark.parametrize("with_m1", [False, True])
def test_tube_geometry(shape, with_m1):
    x = shape()
    m1 = material_m1(x) if with_m1 else None
    cols = np.linspace([0, 0, 255], [255, 0, 0], N).astype(np.uint8)
    m = tube_mesh(x, R, m1=m1, colors=cols, sides=K)
    assert m.vertices.shape == (vertex_count(N, K), 3) == (N * K + 2 * (K + 1), 3)
    assert m.faces.shape == ((N - 1) * K * 2 + 2 * K, 3)
    assert m.faces.max() == len(m.vertices) - 1
    for a in (m.vertices, m.normals):
        assert np.all(np.isfinite(a))
    ring = m.vertices[: N * K].reshape(N, K, 3).astype(np.float64)
    # every ring is a circle of the rod's radius around its node, in the plane normal to the node tangent
    dist = np.linalg.norm(ring - x[:, None, :], axis=2)
    np.testing.assert_allclose(dist, R, rtol=1e-5)
    t, d1, d2 = node_frames(x, m1)
    assert np.abs(np.einsum("nkc,nc->nk", ring - x[:, None, :], t)).max() < 1e-6
    # normals: unit, outward (radial on the rings, ∓ tangent on the start / end caps)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, rtol=1e-5)
    radial = (ring - x[:, None, :]).reshape(-1, 3) / R
    np.testing.assert_allclose(m.normals[: N * K], radial, atol=1e-5)
    np.testing.assert_allclose(m.normals[N * K: N * K + K + 1], np.tile(-t[0], (K + 1, 1)), atol=1e-6)
    np.testing.assert_allclose(m.normals[-(K + 1):], np.tile(t[-1], (K + 1, 1)), atol=1e-6)
    # faces wind counter-clockwise seen from outside: every face normal points like its vertices' normals
    v = m.vertices.astype(np.float64)
    f = m.faces
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(np.einsum("fc,fc->f", fn, m.normals[f].sum(axis=1)) > 0)
    # one colour per ring, the node's
    np.testing.assert_array_equal(m.colors[: N * K].reshape(N, K, 3), np.repeat(cols[:, None], K, axis=1))


def test_ring_follows_the_material_frame():
    """With m1 given, the first vertex of each ring points along m1 (the rings turn with the twist)."""
    x = straight()
    ang = np.linspace(0.0, 2.0, N - 1)
    m1 = np.stack([np.cos(ang), np.sin(ang), np.zeros(N - 1)], 1)
    m = tube_mesh(x, R, m1=m1, sides=K)
    first = (m.vertices[: N * K].reshape(N, K, 3)[:, 0] - x) / R
    mid = 0.5 * (m1[:-1] + m1[1:])
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    np.testing.assert_allclose(first[1:-1], mid, atol=1e-5)


def test_faces_are_cached_and_bad_input_is_refused():
    assert tube_faces(N, K) is tube_faces(N, K)
    with pytest.raises(ValueError, match="finite"):
        tube_mesh(np.full((N, 3), np.nan), R)
    with pytest.raises(ValueError, match=r"\(N >= 2, 3\)"):
        tube_mesh(np.zeros((1, 3)), R)
    with pytest.raises(ValueError, match="colors"):
        tube_mesh(straight(), R, colors=np.zeros((3, 3), np.uint8))


def test_tube_of_a_non_uniform_rod_follows_the_node_radii():
    """Per-node radii (a tapered rod): every ring lies at its node's radius from the centreline, the caps at the
    end nodes' radii; wrong shapes and non-positive radii are refused."""
    x = straight()
    r = np.linspace(0.03, 0.01, N)
    m = tube_mesh(x, r, sides=K)
    ring = m.vertices[: N * K].reshape(N, K, 3).astype(np.float64)
    dist = np.linalg.norm(ring - x[:, None, :], axis=2)
    np.testing.assert_allclose(dist, np.repeat(r[:, None], K, axis=1), rtol=1e-6)
    cap0 = m.vertices[N * K: N * K + K].astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(cap0 - x[0], axis=1), r[0], rtol=1e-6)
    with pytest.raises(ValueError, match=r"per-node radii must be \(N,\)"):
        tube_mesh(x, r[:-1])
    with pytest.raises(ValueError, match="radius > 0"):
        tube_mesh(x, np.where(np.arange(N) == 3, 0.0, r))


def test_live_frame_carries_the_node_radii_of_a_non_uniform_rod():
    """The workbench's live session of the shipped tapered cantilever hands the tube its per-node radii (the
    larger of each node's two edges', as contact uses); a uniform rod hands none."""
    from pathlib import Path

    from sim import load_scene
    from workbench.session.simbridge import LiveSim

    root = Path(__file__).resolve().parents[3] / "assets" / "scenes"
    live = LiveSim(load_scene(root / "tapered_cantilever.toml"))
    fr = live.frame()
    er = live.model.edge_radius
    assert fr.node_radius is not None and fr.node_radius[0] == er[0] and fr.node_radius[-1] == er[-1]
    np.testing.assert_array_equal(fr.node_radius[1:-1], np.maximum(er[:-1], er[1:]))
    assert LiveSim(load_scene(root / "arm.toml")).frame().node_radius is None


def test_glb_is_one_mesh_with_vertex_colours():
    x = sharp()
    cols = np.tile(np.array([[255, 0, 0]], np.uint8), (N, 1))
    cols[-1] = (0, 0, 255)
    m = tube_mesh(x, R, colors=cols, sides=K)
    data = glb_bytes(m)
    assert data[:4] == b"glTF" and len(data) % 4 == 0
    scene = trimesh.load(io.BytesIO(data), file_type="glb", process=False)
    meshes = list(scene.geometry.values())
    assert len(meshes) == 1
    got = meshes[0]
    np.testing.assert_allclose(got.vertices, m.vertices, atol=1e-6)
    np.testing.assert_array_equal(got.faces, m.faces)
    assert got.volume > 0  # closed and outward: the volume is positive ...
    length = np.linalg.norm(np.diff(x, axis=0), axis=1).sum()
    polygon = 0.5 * K * np.sin(2.0 * np.pi / K) * R**2  # cross-section of a ring of K vertices
    assert got.volume == pytest.approx(polygon * length, rel=0.05)  # ... and about a prism's (sharp fold included)


class _Handle(types.SimpleNamespace):
    def remove(self):
        pass


class _Scene:
    def __getattr__(self, name):
        return lambda *a, **k: _Handle(visible=k.get("visible", True), points=None, position=None, wxyz=None,
                                       glb_data=None, batched_positions=None, batched_scales=None)


class _Server:
    scene = _Scene()

    def atomic(self):
        import contextlib

        return contextlib.nullcontext()


def _overlays(**kw):
    from workbench.view.scene import Overlays

    return Overlays(**kw)


def test_trail_keeps_two_seconds_and_clears_when_time_goes_back():
    from workbench.view.rod import TRAIL_SECONDS, RodView

    rod = RodView(_Server(), N)
    rod.set_scene(straight(), (2, 6, 10, 14, 18), R)
    ov = _overlays()
    x = straight()
    for i in range(100):
        y = x.copy()
        y[-1, 0] = 0.01 * i
        rod.render(Frame(node_pos=y, rod_radius=R, time=0.05 * i), np.zeros((N, 3), np.uint8), ov)
        rod.flush()
    tr = rod.trail_positions()
    assert len(tr) == int(TRAIL_SECONDS / 0.05) + 1
    assert tr[-1][0] == pytest.approx(0.99) and tr[0][0] == pytest.approx(0.99 - TRAIL_SECONDS / 0.05 * 0.01)
    assert rod.trail.visible
    np.testing.assert_allclose(rod.controls.batched_positions, x[[2, 6, 10, 14, 18]])
    rod.render(Frame(node_pos=x, rod_radius=R, time=0.0), np.zeros((N, 3), np.uint8), ov)  # a reset
    rod.flush()
    assert len(rod.trail_positions()) == 1 and not rod.trail.visible
    rod.render(Frame(node_pos=x, rod_radius=R, time=0.0), np.zeros((N, 3), np.uint8), _overlays(trail=False))
    rod.flush()
    assert not rod.trail.visible


def test_tip_frame_is_the_last_edges_material_frame():
    from sim.geometry import quat_to_matrix
    from workbench.view.rod import RodView

    rod = RodView(_Server(), N)
    x = sharp()
    m1 = material_m1(x)
    t = np.diff(x, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    m2 = np.cross(t, m1)
    rod.render(Frame(node_pos=x, rod_radius=R, m1=m1, m2=m2), np.zeros((N, 3), np.uint8), _overlays())
    rod.flush()
    assert rod.tip_frame.visible
    np.testing.assert_allclose(rod.tip_frame.position, x[-1])
    Rm = quat_to_matrix(np.asarray(rod.tip_frame.wxyz))
    np.testing.assert_allclose(Rm, np.stack([m1[-1], m2[-1], t[-1]], axis=-1), atol=1e-9)
    rod.render(Frame(node_pos=x, rod_radius=R), np.zeros((N, 3), np.uint8), _overlays())  # no frames known
    rod.flush()
    assert not rod.tip_frame.visible


def test_double_buffer_shows_each_mesh_after_the_next_frame_or_the_delay():
    from workbench.view.rod import SWAP_DELAY, DoubleBufferedGlb

    buf = DoubleBufferedGlb(_Server(), "/t", b"0")
    a, b = buf.nodes
    assert a.visible and not b.visible
    buf.put(b"1")
    assert b.glb_data == b"1" and a.visible and not b.visible  # parsed while hidden
    buf.put(b"2")
    assert b.visible and not a.visible and a.glb_data == b"2"
    from tools.browser import wait_for

    assert SWAP_DELAY > 0 and buf.pending  # shown by the timer, however late it fires on a busy machine
    wait_for(lambda: not buf.pending, what="the delayed swap")
    assert a.visible and not b.visible
    buf.set_visible(False)
    assert not a.visible and not b.visible
    buf.put(b"3")
    buf.flush()
    assert not a.visible and not b.visible


@pytest.mark.parametrize("rpy", [(0.0, 0.0, 0.0), (30.0, -20.0, 100.0), (-170.0, 80.0, -45.0), (90.0, 0.0, 180.0)])
def test_rpy_round_trip(rpy):
    q = quat_from_rpy_deg(rpy)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    back = rpy_deg_from_quat(q)
    np.testing.assert_allclose(quat_from_rpy_deg(back) * np.sign(np.dot(quat_from_rpy_deg(back), q)), q, atol=1e-9)
    if abs(rpy[1]) < 89.0:
        np.testing.assert_allclose(back, rpy, atol=1e-7)


def test_rpy_convention_is_z_y_x():
    """R = Rz(yaw) Ry(pitch) Rx(roll): a yaw of 90° turns +x into +y; a pitch of 90° turns +x into -z."""
    from sim.geometry import quat_to_matrix

    np.testing.assert_allclose(quat_to_matrix(quat_from_rpy_deg((0, 0, 90))) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(quat_from_rpy_deg((0, 90, 0))) @ [1, 0, 0], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(quat_from_rpy_deg((90, 0, 0))) @ [0, 1, 0], [0, 0, 1], atol=1e-12)


def test_target_and_its_frame_hide_when_a_frame_has_no_target():
    """A task frame shows the target and its orientation frame; the next frame without a target (teleop after the
    task, or another task) hides both."""
    import viser

    from workbench.view.scene import SceneView

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = SceneView(server, N, env_map=False)
        x = straight()
        view.render(Frame(node_pos=x, rod_radius=R, targets=np.array([[0.3, 0.0, 0.5]]),
                          target_wxyz=np.array([1.0, 0.0, 0.0, 0.0])))
        view.flush()
        assert view.target.visible and view.target_frame.visible
        view.render(Frame(node_pos=x, rod_radius=R))
        view.flush()
        assert not view.target.visible and not view.target_frame.visible
        view.rod.tube.close()
    finally:
        server.stop()


def test_each_control_point_is_labelled_with_its_node():
    """The beads say which node they are (the teleop sliders name the same nodes) and follow the rod; hidden with
    the control points."""
    import viser

    from workbench.view.rod import RodView

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)  # real handles: labels keep their text
    rod = RodView(server, N)
    try:
        _labels_follow_the_control_points(rod)
    finally:
        rod.tube.close()  # no swap after the server stopped
        server.stop()


def _labels_follow_the_control_points(rod) -> None:
    nodes = (2, 6, 10, 14, 18)
    rod.set_scene(straight(), nodes, R)
    x = sharp()
    rod.render(Frame(node_pos=x, rod_radius=R), np.zeros((N, 3), np.uint8), _overlays())
    rod.flush()
    assert [lab.text for lab in rod.control_labels] == [f"node {c}" for c in nodes]
    assert all(lab.visible for lab in rod.control_labels)
    for lab, c in zip(rod.control_labels, nodes):
        np.testing.assert_allclose(lab.position, x[c] + 1.5 * R)
    rod.render(Frame(node_pos=x, rod_radius=R), np.zeros((N, 3), np.uint8), _overlays(control_points=False))
    rod.flush()
    assert not any(lab.visible for lab in rod.control_labels)
    rod.set_scene(straight(), (3, 9), R)  # other control nodes: other labels
    assert [lab.text for lab in rod.control_labels] == ["node 3", "node 9"]


def test_each_frame_is_shown_whole_with_its_tube():
    """The tube of a frame is shown a frame later (the page parses it while hidden); the frame's target, tip frame,
    control points and trail are shown in the same batch as that tube, never ahead of it (a playing Follow Target
    run showed the target and tip axes 20-30 cm from the tube's tip); flush shows the newest frame whole."""
    import viser

    from workbench.view.scene import SceneView

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        view = SceneView(server, N, env_map=False)
        view.set_rod_scene(straight(), (2, 6, 10, 14, 18), R)
        for name in ("trail", "tip_frame", "control_points"):
            setattr(view.overlays, name, True)
        frames, sent = [], []
        for k in range(6):
            x = straight()
            x[:, 0] += 0.05 * k * np.linspace(0.0, 1.0, N) ** 2  # bends further each frame
            m1 = material_m1(x)
            e = np.diff(x, axis=0)
            m2 = np.cross(e / np.linalg.norm(e, axis=1, keepdims=True), m1)
            frames.append(Frame(node_pos=x, rod_radius=R, time=0.1 * k, targets=x[-1:] + [0.0, 0.0, 0.05],
                                m1=m1, m2=m2))
            view.render(frames[-1])
            buf = view.rod.tube
            sent.append(buf.nodes[1 - buf.front].glb_data)  # parsed while hidden
            if k == 0:
                continue
            shown = frames[k - 1]  # what the page shows now: the previous frame, all of it
            assert buf.visible_node.glb_data == sent[k - 1] and buf.visible_node.visible
            np.testing.assert_allclose(view.target.position, shown.targets[0])
            np.testing.assert_allclose(view.rod.tip_frame.position, shown.node_pos[-1])
            np.testing.assert_allclose(view.rod.controls.batched_positions, shown.node_pos[[2, 6, 10, 14, 18]])
            np.testing.assert_allclose(view.rod.trail_positions()[-1], shown.node_pos[-1])
        view.flush()
        last = frames[-1]
        assert view.rod.tube.visible_node.glb_data == sent[-1]
        np.testing.assert_allclose(view.target.position, last.targets[0])
        np.testing.assert_allclose(view.rod.tip_frame.position, last.node_pos[-1])
        view.rod.tube.close()
    finally:
        server.stop()
