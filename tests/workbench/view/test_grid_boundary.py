"""Fixes and loads in the grid of envs (workbench.view.grid): every env's fixed nodes, fixed twists and point loads
are drawn at its own nodes, in its own cell, by one batched scene node per kind of glyph (not one per env); a load
acts by its env's own time; the labels are the focused env's; the "Fixes and loads" toggle hides them all."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.geometry import quat_to_matrix
from workbench.session.grid import GridSession
from workbench.view.boundary import boundary_of
from workbench.view.grid import GridView
from workbench.view.scene import ARROW_MAX, Overlays


@pytest.fixture(scope="module")
def session():
    s = GridSession("follow_target", "zero", 3)
    for _ in range(2):
        s.step()
    yield s
    s.core.close()


@pytest.fixture
def server():
    import viser

    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


def _with_loads(b):
    """The task's fixes plus two loads on the tip: one always on, one only in [0.5, 1) s."""
    n = b.n_nodes
    return dataclasses.replace(b, load_nodes=np.array([n - 1, n // 2]),
                               load_force=np.array([[0.0, 0.0, -2.0], [0.5, 0.0, 0.0]]),
                               load_torque=np.array([0.0, 0.0]), load_window=np.array([[0.0, np.inf], [0.5, 1.0]]))


def test_every_env_has_its_glyphs_at_its_own_nodes(session, server):
    s = session
    b = boundary_of(s.core.model)
    assert len(b.fixed_nodes) and len(b.twist_edges)  # the arm's clamp: fixed nodes and a fixed twist
    ov = Overlays()
    view = GridView(server, s, overlays=ov)
    try:
        view.render()
        x = s.positions()
        g = view.boundary
        assert g.fixed.visible and g.rings.visible and g.arrows is None and g.labels == []  # no loads: no arrows
        assert len(g.nodes) == 2  # one batched node per kind of glyph, for all envs
        np.testing.assert_allclose(g.fixed.batched_positions, x[:, b.fixed_nodes].reshape(-1, 3), atol=1e-6)
        assert len(g.fixed.batched_colors) == s.n * len(b.fixed_nodes)
        e = b.twist_edges
        np.testing.assert_allclose(g.rings.batched_positions, (0.5 * (x[:, e] + x[:, e + 1])).reshape(-1, 3),
                                   atol=1e-6)
        t = x[2, e[0] + 1] - x[2, e[0]]
        np.testing.assert_allclose(quat_to_matrix(g.rings.batched_wxyzs[-len(e)])[:, 2], t / np.linalg.norm(t),
                                   atol=1e-5)
        # each env's glyphs lie in its own cell
        cells = g.fixed.batched_positions.reshape(s.n, -1, 3)[:, 0, :2] - s.offsets[:, :2]
        assert np.abs(cells - cells[0]).max() < 1e-6
        ov.boundary = False  # the main view's "Fixes and loads" toggle
        view.render()
        assert not any(h.visible for h in g.nodes)
        ov.boundary = True
        view.render()
        assert all(h.visible for h in g.nodes)
    finally:
        view.remove()


def test_loads_by_env_time_and_the_focused_envs_labels(session, server):
    s = session
    b = _with_loads(boundary_of(s.core.model))
    ov = Overlays(arrows="linear", force_scale=0.1)
    view = GridView(server, s, overlays=ov, boundary=b)
    time = s.core.state.time
    saved = np.array(time, copy=True)
    try:
        time[:] = [0.0, 0.7, 0.2]  # env 1 inside the second load's window
        view.render()
        g = view.boundary
        x = s.positions()
        pts = np.asarray(g.arrows.points, np.float64)
        assert pts.shape == (4, 2, 3)  # the tip load of every env, the windowed one of env 1
        n = b.n_nodes
        np.testing.assert_allclose(pts[:, 0], [x[0, n - 1], x[1, n - 1], x[1, n // 2], x[2, n - 1]], atol=1e-6)
        np.testing.assert_allclose(pts[:, 1] - pts[:, 0], [[0, 0, -0.2], [0, 0, -0.2], [0.05, 0, 0], [0, 0, -0.2]],
                                   atol=1e-6)
        assert len(g.labels) == 2 and [lab.visible for lab in g.labels] == [True, False]  # env 0: one load acts
        np.testing.assert_allclose(g.labels[0].position, pts[0, 1], atol=1e-6)
        assert g.labels[0].text == "2 N"
        view.focus = 1
        view.render()
        assert [lab.text for lab in g.labels if lab.visible] == ["2 N", "0.5 N"]
        np.testing.assert_allclose(g.labels[1].position, pts[2, 1], atol=1e-6)  # env 1's windowed load
        ov.arrows = "auto"
        view.render()
        d = np.linalg.norm(np.diff(np.asarray(g.arrows.points), axis=1)[:, 0], axis=1)
        assert d.max() == pytest.approx(ARROW_MAX)
    finally:
        time[:] = saved
        view.remove()
