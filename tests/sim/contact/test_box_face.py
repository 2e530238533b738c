"""A rod lying on a flat box face, or on the flat face of a triangle mesh (docs/physics.md §4.5): the contact acts
per node over a face, so it neither jumps between an edge's ends nor rocks the rod; Newton converges with the
default settings and the rod comes to rest, and slides across the face (over the triangles' shared edges)
smoothly."""
from __future__ import annotations

import numpy as np
import pytest

from sim import Simulator, build_model, parse_scene
from tests.helpers.paths import REPO

R = 0.01
ROD = dict(nodes=11, length=0.5, radius=R, density=1000.0, youngs_modulus=1e7, poisson_ratio=0.5,
           start=[-0.25, 0.0, R + 4e-3], direction=[1.0, 0.0, 0.0], clamp="none")
BOX = dict(type="box", position=[0.0, 0.0, -0.05], half_extents=[0.6, 0.2, 0.05])
# the same slab as a 12-triangle mesh (assets/meshes/unit_box.obj: the unit cube centred at the origin)
MESH = dict(type="mesh", file=str(REPO / "assets" / "meshes" / "unit_box.obj"), scale=[1.2, 0.4, 0.1],
            position=[0.0, 0.0, -0.05])
DELTA = 5e-3
KINDS = pytest.mark.parametrize("obstacle", [BOX, MESH], ids=["box", "mesh"])


def make(gravity=(0.0, 0.0, -9.8), obstacle=BOX):
    doc = {"sim": dict(dt=0.01, gravity=list(gravity), newton_tol=1e-6, newton_max_iter=5, accept_unconverged=True),
           "rod": dict(ROD), "obstacle": [dict(obstacle)]}
    sim = Simulator(build_model(parse_scene(doc, None)), envs=1)
    return sim, sim.reset(), sim.make_control()


@KINDS
def test_rod_on_box_face_converges_and_rests(obstacle):
    """Released 4 mm above the top face: every step converges, after 5 s every node is at rest (speed below
    1e-6 m/s; it rocked at 2 cm/s when one contact point per edge jumped between the edge's ends), no
    penetration beyond delta, and the face carries the weight."""
    sim, st, ctrl = make(obstacle=obstacle)
    for i in range(500):
        s = sim.step(st, ctrl)
        assert s.converged[0], i
        assert s.max_penetration[0] < DELTA
    assert np.abs(st.dof_vel[0, :, :3]).max() < 1e-6
    k = int(s.contact_count[0])
    fz = float(np.sum(s.contact_normal_force[0, :k] * s.contact_normal[0, :k, 2]))
    assert abs(fz / float(sim.model.node_mass.sum() * 9.8) - 1.0) < 1e-6


@KINDS
def test_rod_slides_across_box_face_smoothly(obstacle):
    """Frictionless face, a horizontal load of 0.5 m/s² along the rod: every step converges and the rod slides
    with the closed-form acceleration while its vertical velocity stays below 1e-4 m/s (no rocking)."""
    sim, st, ctrl = make(gravity=(0.5, 0.0, -9.8), obstacle=obstacle)
    for _ in range(30):  # land and settle vertically while sliding
        sim.step(st, ctrl)
    x0 = float(st.node_pos[0, :, 0].mean())
    v0 = float(st.node_vel[0, :, 0].mean())
    for i in range(30):
        s = sim.step(st, ctrl)
        assert s.converged[0], i
        assert np.abs(st.dof_vel[0, :, 2]).max() < 1e-4
    T = 0.3
    assert float(st.node_pos[0, :, 0].mean()) - x0 == pytest.approx(v0 * T + 0.5 * 0.5 * T * T, rel=0.02)

