"""Glyphs of the boundary conditions and point loads (workbench.view.boundary): what is read from the model (fixed
nodes by kind, fixed twists, loads), the glyphs following the nodes, arrows along the forces, loads hidden outside
their window, the overlay's toggle, and no scene node at all for a scene without fixes or loads."""
from __future__ import annotations

import dataclasses
import types
from pathlib import Path

import numpy as np
import pytest

from sim import FixSpec, LoadSpec, build_model, load_scene
from sim.geometry import quat_to_matrix
from workbench.view import boundary as vb
from workbench.view.boundary import BoundaryView, boundary_of
from workbench.view.scene import ARROW_MAX, arrow_vectors

SCENES = Path(__file__).resolve().parents[3] / "assets" / "scenes"


def _scene(name: str, **kw):
    spec = load_scene(SCENES / name)
    if "clamp" in kw:
        spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, clamp=kw.pop("clamp")))
    return dataclasses.replace(spec, **kw)


def _model(name: str, **kw):
    return build_model(_scene(name, **kw))


class _Handle(types.SimpleNamespace):
    def remove(self):
        self.removed = True


class _Scene:
    """Records every node added (name -> handle)."""

    def __init__(self):
        self.added: dict[str, _Handle] = {}

    def __getattr__(self, kind):
        def add(name, *a, **k):
            h = _Handle(kind=kind, name=name, visible=k.get("visible", True), text=a[0] if a else "", points=None,
                        position=None, batched_positions=None, batched_wxyzs=None, removed=False, kw=k)
            self.added[name] = h
            return h

        return add


class _Server:
    def __init__(self):
        self.scene = _Scene()


def _bent(n: int) -> np.ndarray:
    """A rod bent into a quarter circle of radius 1 m in the x-z plane (no two edges parallel)."""
    a = np.linspace(0.0, 0.5 * np.pi, n)
    return np.stack([np.sin(a), 0.1 * a, 1.0 - np.cos(a)], 1)


def test_shipped_scenes():
    rope = boundary_of(_model("rope_pinned.toml"))  # pins at both ends, twist of edge 0 fixed
    np.testing.assert_array_equal(rope.fixed_nodes, [0, rope.n_nodes - 1])
    assert [vb.KIND_NAMES[k] for k in rope.fixed_kind] == ["pinned", "pinned"] and rope.fixed_axes == ("xyz", "xyz")
    np.testing.assert_array_equal(rope.twist_edges, [0])
    assert len(rope.load_nodes) == 0 and not rope.empty
    strip = boundary_of(_model("strip_tip_load.toml"))  # clamp = "first_edge", a load on the last node
    np.testing.assert_array_equal(strip.fixed_nodes, [0, 1])
    assert [vb.KIND_NAMES[k] for k in strip.fixed_kind] == ["clamped", "clamped"]
    np.testing.assert_array_equal(strip.twist_edges, [0])  # not the unused twist slot of the last node
    np.testing.assert_array_equal(strip.load_nodes, [strip.n_nodes - 1])
    np.testing.assert_allclose(strip.load_force, [[0.0, 0.0, -0.01]])
    np.testing.assert_allclose(strip.load_window, [[0.0, np.inf]])
    planar = boundary_of(_model("arm_2d.toml"))  # 2-D: both in-plane axes fixed is every axis; no twist
    assert planar.fixed_axes == ("xz", "xz") and [vb.KIND_NAMES[k] for k in planar.fixed_kind] == ["clamped"] * 2
    assert len(planar.twist_edges) == 0


def test_kinds_of_fixed_nodes_and_loads_from_the_tables():
    fixes = (FixSpec(nodes=(3,), axes="z"), FixSpec(nodes=(8, 9), twist_edges=(8,)), FixSpec(nodes=(-1,)),
             FixSpec(twist_edges=(12,)))
    loads = (LoadSpec(node=-2, force=(1.0, 2.0, -3.0), torque=0.25, start=0.1, stop=0.3), LoadSpec(node=5))
    b = boundary_of(_model("rope_pinned.toml", fixes=fixes, loads=loads))
    N = b.n_nodes
    np.testing.assert_array_equal(b.fixed_nodes, [3, 8, 9, N - 1])
    assert b.fixed_axes == ("z", "xyz", "xyz", "xyz")
    assert [vb.KIND_NAMES[k] for k in b.fixed_kind] == ["partial", "clamped", "clamped", "pinned"]
    np.testing.assert_array_equal(b.twist_edges, [8, 12])
    np.testing.assert_array_equal(b.load_nodes, [N - 2, 5])
    np.testing.assert_allclose(b.load_torque, [0.25, 0.0])
    np.testing.assert_allclose(b.load_window, [[0.1, 0.3], [0.0, np.inf]])
    assert list(vb.load_active(b, 0.05)) == [False, True] and list(vb.load_active(b, 0.1)) == [True, True]
    assert list(vb.load_active(b, 0.3)) == [False, True]  # [start, stop)
    assert vb.load_text(b.load_force[0], 0.25) == "3.74 N · 0.25 N·m"
    assert vb.load_text((0.0, 0.0, -0.01), 0.0) == "0.01 N"


def test_nothing_is_created_for_a_scene_without_fixes_or_loads():
    b = boundary_of(_model("rope_pinned.toml", fixes=(), clamp="none"))
    assert b.empty
    server = _Server()
    view = BoundaryView(server)
    view.set_boundary(b)
    assert server.scene.added == {} and view.nodes == []
    view.render(_bent(b.n_nodes), 0.0, True, lambda f: f)  # nothing to draw, nothing sent
    assert server.scene.added == {}
    # a scene with glyphs, then one without: its nodes are removed
    view.set_boundary(boundary_of(_model("strip_tip_load.toml")))
    old = list(server.scene.added.values())
    assert len(old) == 4  # boxes, rings, arrows, one label
    view.set_boundary(b)
    assert all(h.removed for h in old) and view.nodes == []


@pytest.mark.parametrize("mode", ["log", "auto", "linear"])
def test_glyphs_follow_the_nodes_and_arrows_point_along_the_forces(mode):
    fixes = (FixSpec(nodes=(0, 1), twist_edges=(0,)), FixSpec(nodes=(10,), axes="xy"), FixSpec(twist_edges=(15,)))
    loads = (LoadSpec(node=-1, force=(0.0, 0.0, -2.0)), LoadSpec(node=20, force=(0.3, -0.4, 0.5), torque=0.01),
             LoadSpec(node=12, force=(1.0, 0.0, 0.0), start=0.5, stop=1.0))
    b = boundary_of(_model("rope_pinned.toml", fixes=fixes, loads=loads, clamp="none"))
    server = _Server()
    view = BoundaryView(server)
    view.set_boundary(b)
    added = server.scene.added
    assert {h.kind for h in added.values()} == {"add_batched_meshes_simple", "add_arrows", "add_label"}
    assert len(added) == 3 + len(loads)  # one batched node per kind of glyph, one label per load
    np.testing.assert_array_equal(view.fixed.kw["batched_colors"], vb.KIND_COLORS[[0, 0, 2]])
    vec = lambda f: arrow_vectors(f, mode, 0.05)  # noqa: E731
    for x in (_bent(b.n_nodes), _bent(b.n_nodes)[::-1] * 0.5 + 0.2):
        view.render(x, 0.0, True, vec)
        assert view.fixed.visible and view.rings.visible and view.arrows.visible
        np.testing.assert_allclose(view.fixed.batched_positions, x[[0, 1, 10]])
        np.testing.assert_allclose(view.rings.batched_positions, 0.5 * (x[[0, 15]] + x[[1, 16]]))
        for q, e in zip(view.rings.batched_wxyzs, (0, 15)):  # the ring's axis (its +z) along the edge
            t = (x[e + 1] - x[e]) / np.linalg.norm(x[e + 1] - x[e])
            np.testing.assert_allclose(quat_to_matrix(q)[:, 2], t, atol=1e-9)
        pts = view.arrows.points
        assert pts.shape == (2, 2, 3)  # the third load waits for its window
        np.testing.assert_allclose(pts[:, 0], x[[b.n_nodes - 1, 20]])
        d = pts[:, 1] - pts[:, 0]
        f = b.load_force[:2]
        np.testing.assert_allclose(d / np.linalg.norm(d, axis=1, keepdims=True),
                                   f / np.linalg.norm(f, axis=1, keepdims=True), atol=1e-12)
        if mode != "linear":
            assert np.linalg.norm(d, axis=1).max() == pytest.approx(ARROW_MAX)
        shown = [lab for lab in view.labels if lab.visible]
        assert [lab.text for lab in shown] == ["2 N", "0.707 N · 0.01 N·m"]  # the largest first
        np.testing.assert_allclose(shown[0].position, pts[0, 1])
    # the third load inside its window: three arrows; after it: two again
    view.render(x, 0.5, True, vec)
    assert len(view.arrows.points) == 3 and sum(lab.visible for lab in view.labels) == 3
    np.testing.assert_allclose(view.arrows.points[2, 0], x[12])
    assert view.arrows.points[2, 1, 0] > view.arrows.points[2, 0, 0]  # along +x
    view.render(x, 1.0, True, vec)
    assert len(view.arrows.points) == 2 and sum(lab.visible for lab in view.labels) == 2
    # the overlay's toggle hides every glyph, a rod of another node count too
    view.render(x, 0.5, False, vec)
    assert not any(h.visible for h in view.nodes)
    view.render(x, 0.5, True, vec)
    assert all(h.visible for h in view.nodes)
    view.render(x[:-1], 0.5, True, vec)
    assert not any(h.visible for h in view.nodes)


def test_only_windowed_loads_hide_every_arrow_outside_their_windows():
    loads = (LoadSpec(node=-1, force=(0.0, 0.0, 1.0), start=1.0, stop=2.0),)
    b = boundary_of(_model("strip_tip_load.toml", loads=loads))
    view = BoundaryView(_Server())
    view.set_boundary(b)
    x = _bent(b.n_nodes)
    vec = lambda f: arrow_vectors(f, "log", 0.005)  # noqa: E731
    for t, on in ((0.0, False), (0.999, False), (1.0, True), (1.5, True), (2.0, False), (5.0, False)):
        view.render(x, t, True, vec)
        assert view.arrows.visible == on and view.labels[0].visible == on, t
        k, pts = vb.load_arrows(b, x, t, vec(b.load_force))
        assert len(k) == int(on) and pts.shape == (int(on), 2, 3)
    assert view.fixed.visible  # the clamp stays


def test_ring_poses_of_a_straight_rod():
    b = boundary_of(_model("strip_tip_load.toml"))
    x = np.asarray(build_model(_scene("strip_tip_load.toml")).rest_node_pos)
    p, q = vb.ring_poses(b, x)
    np.testing.assert_allclose(p, [0.5 * (x[0] + x[1])])
    np.testing.assert_allclose(quat_to_matrix(q[0])[:, 2], [1.0, 0.0, 0.0], atol=1e-12)  # the rod lies along +x


def test_on_a_viser_server():
    """The handles take the values the view sets (a real viser server, no page)."""
    import viser

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        b = boundary_of(_model("rope_pinned.toml", loads=(LoadSpec(node=15, force=(0.0, 0.1, 0.0), torque=1e-3),)))
        view = BoundaryView(server)
        view.set_boundary(b)
        x = _bent(b.n_nodes)
        view.render(x, 0.0, True, lambda f: arrow_vectors(f, "log", 0.005))
        np.testing.assert_allclose(view.fixed.batched_positions, x[[0, b.n_nodes - 1]], atol=1e-6)
        np.testing.assert_allclose(view.arrows.points[0], [x[15], x[15] + [0.0, ARROW_MAX, 0.0]], atol=1e-6)
        assert view.labels[0].text == "0.1 N · 0.001 N·m" and view.labels[0].visible
        view.set_boundary(None)
        assert view.nodes == []
    finally:
        server.stop()


def test_scene_view_draws_them_for_live_frames_only():
    """``SceneView.render(fr, boundary=False)`` (a replayed recording) and the "Fixes and loads" overlay off hide
    the glyphs; the arrows take the contact arrows' scale."""
    import viser

    from workbench.session.frame import Frame
    from workbench.view.scene import SceneView

    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        model = _model("strip_tip_load.toml")
        view = SceneView(server, model.node_count, env_map=False)
        assert view.boundary.nodes == []
        view.set_boundary(boundary_of(model))
        x = np.asarray(model.rest_node_pos, np.float64)
        fr = Frame(node_pos=x, rod_radius=float(model.radius_max), time=0.0)
        view.render(fr)
        view.flush()
        assert all(h.visible for h in view.boundary.nodes)
        view.overlays.arrows, view.overlays.force_scale = "linear", 2.0
        view.render(fr)
        view.flush()
        np.testing.assert_allclose(view.boundary.arrows.points[0], [x[-1], x[-1] + [0.0, 0.0, -0.02]], atol=1e-6)
        view.render(fr, boundary=False)
        view.flush()
        assert not any(h.visible for h in view.boundary.nodes)
        view.overlays.boundary = False
        view.render(fr)
        view.flush()
        assert not any(h.visible for h in view.boundary.nodes)
        view.rod.tube.close()  # no delayed tube swap after the server stops
    finally:
        server.stop()
