"""Several rods in the workbench (docs/physics.md §1.7): each rod is its own tube (the edge joining two rods of the
chain is not drawn), colours are per rod, the boundary glyphs leave the joint alone; and in a real browser the
two-rod scene loads and draws two tubes."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim import build_model, load_scene
from workbench.session.coloring import node_values
from workbench.session.frame import Frame
from workbench.view.boundary import boundary_of
from workbench.view.tube import SIDES, rods_mesh, tube_mesh, vertex_count

SCENES = Path(__file__).resolve().parents[3] / "assets" / "scenes"


def _chain():
    x = np.zeros((9, 3))
    x[:5, 0] = np.linspace(0.0, 1.0, 5)
    x[5:, 1] = 1.0
    x[5:, 0] = np.linspace(0.0, 1.0, 4)
    return x, np.array([0, 5, 9])


def test_rods_mesh_is_one_capped_tube_per_rod():
    x, off = _chain()
    m = rods_mesh(x, 0.05, off)
    a, b = tube_mesh(x[:5], 0.05), tube_mesh(x[5:], 0.05)
    assert len(m.vertices) == vertex_count(5) + vertex_count(4)
    np.testing.assert_array_equal(m.vertices, np.concatenate([a.vertices, b.vertices]))
    split = vertex_count(5)
    crosses = (m.faces < split).any(axis=1) & (m.faces >= split).any(axis=1)
    assert not crosses.any()  # no triangle joins the two rods
    one = rods_mesh(x[:5], 0.05, None)
    np.testing.assert_array_equal(one.faces, a.faces)


def test_node_colours_are_per_rod():
    x, off = _chain()
    fr = Frame(node_pos=x, rod_radius=0.05, rod_offsets=off)
    v = node_values(fr, "curvature")
    assert v.shape == (9,) and np.allclose(v, 0.0)  # two straight rods: the jump between them bends nothing


def test_boundary_of_two_rods_names_loads_by_rod():
    import dataclasses

    from sim.scene.boundary import LoadSpec

    spec = load_scene(SCENES / "two_rods.toml")
    spec = dataclasses.replace(spec, loads=(LoadSpec(rod="cross", node=-1, force=(0.0, 0.0, 1.0)),))
    b = boundary_of(build_model(spec))
    assert b.load_nodes.tolist() == [41]
    assert len(b.twist_edges) == 0  # the joint edge's fixed twist is no boundary of either rod


def test_rod_on_rod_contact_is_drawn_as_contact_forces():
    """The crossing of the two-rod scene, once "cross" lies on "base": the contact arrows the view draws
    (``contacts_from_stats``) include the edge pairs', pushing "cross" up and "base" down by equal amounts."""
    from sim import Simulator
    from workbench.session.simbridge import contacts_from_stats

    model = build_model(load_scene(SCENES / "two_rods.toml"))
    sim = Simulator(model, envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    for _ in range(150):
        stats = sim.step(state, ctrl)
    assert not stats.failed.any()
    points, forces, normals, _ = contacts_from_stats(stats)
    k = int(stats.contact_count[0])
    pair = stats.contact_obstacle[0, :k] == -1
    assert pair.sum() >= 2 and len(points) == k
    x = state.node_pos[0]
    on_cross = stats.contact_edge[0, :k] >= model.rod_node_offsets[1]
    up, down = forces[pair & on_cross], forces[pair & ~on_cross]
    assert len(up) == len(down) and (up[:, 2] > 0).all() and (down[:, 2] < 0).all()
    np.testing.assert_allclose(up.sum(axis=0), -down.sum(axis=0), atol=1e-12)
    crossing = points[pair]  # at the middle of both rods, between their centre lines
    assert np.abs(crossing[:, :2]).max() < 0.05 and (crossing[:, 2] > 0.0).all()
    assert crossing[:, 2].max() < x[model.rod_node_offsets[1]:, 2].max() + 1e-9
    assert up[:, 2].sum() > 1.0  # newtons: a good part of the weight of "cross" (≈ 9.9 N), the rest on the floor


@pytest.mark.browser
def test_two_rod_scene_loads_and_draws_two_tubes(wb_page):
    from tools.browser import wait_for

    app, page = wb_page
    wb = app.wb
    try:
        wb.load_scene(SCENES / "two_rods.toml")
        f = wb.frame_index
        wait_for(lambda: wb.frame_index > f + 5, timeout=60, what="the two-rod scene to step")
        app.request_render()
        wait_for(lambda: app.view.rod.last_mesh is not None
                 and len(app.view.rod.last_mesh.vertices) == 2 * vertex_count(21, SIDES),
                 timeout=30, what="two tubes of 21 nodes")
        assert wb.live.model.rod_names == ("base", "cross")
        f = wb.frame_index
        wait_for(lambda: wb.frame_index > f + 3, what="a few more steps of the two rods")
        assert np.isfinite(app.view.rod.last_mesh.vertices).all()
        # the Teleop tab offers the two rods; choosing "cross" in the page makes the sliders steer it
        page.get_by_role("tab", name="Teleop", exact=True).click()
        wait_for(lambda: app.controls.rod.visible, what="the Rod dropdown")
        page.get_by_role("combobox", name="Rod", exact=True).click()
        page.get_by_role("option", name="cross", exact=True).click()
        wait_for(lambda: wb.teleop_rod == 1, what="the page to choose rod 'cross'")
        assert wb.teleop.first_node == int(wb.live.rod_offsets[1])
    finally:
        wb.load_scene(SCENES / "default.toml")
