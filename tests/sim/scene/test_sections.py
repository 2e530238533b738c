"""Non-circular sections against beam theory (docs/physics.md §1.5, §8D): a rectangular strip (and an elliptic
rod) cantilever under a small tip force bends about its weak or strong axis; the tip deflections are in the ratio
of the second moments and each matches F L'³/(3 E I)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.scene.boundary import LoadSpec
from sim.scene.section import section_of
from tests.helpers.rodspec import make_spec
from tests.helpers.statics import static_solve


def _tip(rod_kw, force, mode="3d", N=21):
    spec = make_spec(nodes=N, E=1e7, dt=1e4, dtol=1e-14, max_iter=100, mode=mode)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, **rod_kw),
                               loads=(LoadSpec(node=-1, force=force),))
    sim, state, stats = static_solve(spec, steps=3)
    assert stats.converged.all()
    p = state.node_pos[0]
    return sim.model, p[-1] - 0.5 * (p[0] + p[1])


@pytest.mark.parametrize("rod_kw", [dict(cross_section="rectangle", width=0.04, height=0.01),
                                    dict(cross_section="ellipse", semi_axes=(0.02, 0.005))],
                         ids=["rectangle", "ellipse"])
def test_strip_cantilever_weak_vs_strong_axis(rod_kw):
    """Rod along +x: m1 = +y (width / first semi-axis), m2 = +z. A force along z bends it about m1 (κ2, I2: the
    weak axis), one along y about m2 (κ1, I1: the strong axis): δz/δy = I1/I2 (16 for these sections)."""
    F = 1e-4
    m, tz = _tip(rod_kw, (0.0, 0.0, -F))
    _, ty = _tip(rod_kw, (0.0, F, 0.0))
    sec = section_of(m.spec.rod)
    assert sec.I1 / sec.I2 == pytest.approx(16.0)
    ratio = -tz[2] / ty[1]
    assert ratio == pytest.approx(sec.I1 / sec.I2, rel=1e-3), ratio
    Lf = 1.0 - 0.5 * m.rest_edge_length[0]
    assert -tz[2] == pytest.approx(F * Lf ** 3 / (3 * m.EI2_max), rel=5e-3)
    assert ty[1] == pytest.approx(F * Lf ** 3 / (3 * m.EI1_max), rel=5e-3)
    assert abs(tz[1]) < 1e-12 and abs(ty[2]) < 1e-12  # principal axes: no coupling


def test_planar_strip_bends_with_its_in_plane_stiffness():
    """2-D, rod along +x: the in-plane component is κ2, so the planar strip bends with EI2 like the 3-D one."""
    kw = dict(cross_section="rectangle", width=0.04, height=0.01)
    _, t3 = _tip(kw, (0.0, 0.0, -1e-4))
    _, t2 = _tip(kw, (0.0, 0.0, -1e-4), mode="2d")
    assert np.allclose(t2, t3, rtol=1e-6, atol=1e-12)
