"""Non-uniform rods: per-edge radius and Young's modulus (docs/physics.md §1.5). A stepped cantilever under a tip
load against beam theory (with convergence in N), masses from the per-edge sections, contact with each edge's own
radius, uniform lists equal to the scalar keys bit for bit, and the scene keys' checks and round trip."""
from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model
from sim.scene.boundary import LoadSpec
from sim.scene.obstacles import CapsuleSpec, PlaneSpec
from sim.scene.spec import parse_scene, scene_to_toml
from sim.scene.tomlio import SceneError
from tests.helpers.rodspec import make_spec, small_scene_toml
from tests.helpers.statics import static_solve

R_ROOT, R_TIP = 0.02, 0.01   # thick inner half, thin outer half: a stiffness ratio of 16
E = 1e7


def _stepped(N, F):
    """A cantilever of length 1 whose edges up to x = 0.5 have radius R_ROOT and the rest R_TIP (the step at the
    middle node for odd N), a tip load F (-z)."""
    s = np.linspace(0.0, 1.0, N)
    mid = 0.5 * (s[:-1] + s[1:])
    rs = tuple(float(R_ROOT if m < 0.5 else R_TIP) for m in mid)
    spec = make_spec(nodes=N, length=1.0, radius=R_ROOT, E=E, dt=1e4, dtol=1e-14, max_iter=100)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, edge_radius=rs),
                               loads=(LoadSpec(node=-1, force=(0.0, 0.0, -F)),))
    sim, state, stats = static_solve(spec, steps=3)
    assert stats.converged.all()
    p = state.node_pos[0]
    return sim.model, p[-1] - 0.5 * (p[0] + p[1])  # from the effective built-in end (middle of the clamped edge)


def _stepped_beam_tip(F, L, a, EIa, EIb):
    """Tip deflection of a cantilever of length L with EIa over [0, a] and EIb over [a, L] under a tip load F
    (unit-load method: δ = ∫ F (L − x)² / EI(x) dx)."""
    return F / 3.0 * ((L ** 3 - (L - a) ** 3) / EIa + (L - a) ** 3 / EIb)


def stepped_cantilever_errors(Ns=(21, 41, 81), F=1e-5):
    """Relative tip-deflection errors of the stepped cantilever against the two-segment beam formula."""
    EIa, EIb = E * np.pi * R_ROOT ** 4 / 4, E * np.pi * R_TIP ** 4 / 4
    errs = []
    for N in Ns:
        m, tip = _stepped(N, F)
        assert abs(tip[1]) < 1e-12
        x0 = 0.5 * m.rest_edge_length[0]
        ref = _stepped_beam_tip(F, 1.0 - x0, 0.5 - x0, EIa, EIb)
        errs.append((-tip[2] - ref) / ref)
    return np.array(errs)


def test_stepped_cantilever_matches_beam_theory_to_second_order():
    """A radius step 20 → 10 mm halfway (EI ratio 16): the node at the step carries the compliance mean of its two
    edges (its Voronoi cell is half in each), so the tip deflection approaches the two-segment beam formula with
    the square of the edge length (the built-in end is the middle of edge 0). The arithmetic mean of the two EI
    would make the rod over-stiff by 4.3 % at N = 41, an error that only halves with each doubling of N."""
    errs = stepped_cantilever_errors()
    assert abs(errs[1]) < 1e-3, errs
    assert 3.5 < errs[0] / errs[1] < 4.5 and 3.5 < errs[1] / errs[2] < 4.5, errs  # second order in l̄


def test_masses_and_stiffnesses_follow_the_per_edge_sections():
    """Node masses are half of each adjacent edge's ρ π r_j² l_j (their sum the rod's mass), EA is per edge and
    the bending/twisting stiffness of an interior node is the harmonic mean of its two edges' (equal edges)."""
    N, rho, nu = 6, 800.0, 0.4
    r = np.array([0.03, 0.025, 0.02, 0.015, 0.01])
    E = np.array([1e6, 2e6, 3e6, 4e6, 5e6])
    spec = make_spec(nodes=N, length=1.0, radius=0.03, density=rho, E=5e6, nu=nu)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, edge_radius=tuple(r),
                                                             edge_youngs_modulus=tuple(E)))
    m = build_model(spec)
    lbar = m.rest_edge_length
    np.testing.assert_allclose(m.node_mass.sum(), (rho * np.pi * r ** 2 * lbar).sum(), rtol=1e-14)
    np.testing.assert_allclose(m.node_mass[0], 0.5 * rho * np.pi * r[0] ** 2 * lbar[0], rtol=1e-14)
    np.testing.assert_allclose(m.edge_EA, E * np.pi * r ** 2, rtol=1e-14)
    EI = E * np.pi * r ** 4 / 4
    GJ = EI * 2 / (2 * (1 + nu))
    harm = lambda k: 2.0 / (1.0 / k[:-1] + 1.0 / k[1:])  # noqa: E731
    np.testing.assert_allclose(m.node_EI1[1:-1], harm(EI), rtol=1e-14)
    np.testing.assert_allclose(m.node_EI2[1:-1], harm(EI), rtol=1e-14)
    np.testing.assert_allclose(m.node_GJ[1:-1], harm(GJ), rtol=1e-14)
    np.testing.assert_allclose(m.node_EI1[[0, -1]], EI[[0, -1]], rtol=1e-14)
    np.testing.assert_allclose(m.edge_radius, r)
    assert m.radius_max == r.max() and m.EA_max == pytest.approx((E * np.pi * r ** 2).max())


def test_node_stiffness_weights_the_compliances_by_the_half_edges():
    """Unequal edges: an interior node's compliance is the mean of its edges' compliances weighted by the half-edge
    lengths, K_i = (l_a + l_b)/(l_a/K_a + l_b/K_b); equal stiffnesses give exactly their value, whatever the
    lengths."""
    pts = [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.4, 0.0, 0.0], [0.5, 0.0, 0.0], [0.9, 0.0, 0.0]]
    Es = (1e6, 3e6, 3e6, 5e5)
    spec = make_spec(nodes=5, length=0.9, radius=0.01, E=3e6)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, rest_points=tuple(map(tuple, pts)),
                                                             edge_youngs_modulus=Es))
    m = build_model(spec)
    la, EI = m.rest_edge_length, np.array(Es) * np.pi * 0.01 ** 4 / 4
    want = (la[:-1] + la[1:]) / (la[:-1] / EI[:-1] + la[1:] / EI[1:])
    np.testing.assert_allclose(m.node_EI1[1:-1], want, rtol=1e-14)
    assert m.node_EI1[2] == EI[1]  # equal neighbours: the same float
    uni = build_model(dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, edge_youngs_modulus=None)))
    assert np.all(uni.node_EI1 == uni.EI1_max) and np.all(uni.node_GJ == uni.GJ_max)


def test_uniform_lists_step_bit_for_bit_like_the_scalar_keys():
    """radius/youngs_modulus given as lists of equal values is the same rod: the same bits after 20 steps of the
    arm under a curvature command, against a capsule (contact path included)."""
    spec = make_spec(nodes=21, length=1.0, radius=0.02, E=1e6, dt=0.02, gravity=(0.0, 0.0, -9.81), max_iter=5,
                     accept=True, tol=1e-6)
    spec = dataclasses.replace(spec, obstacles=(CapsuleSpec(start=(0.5, -0.5, -0.08), end=(0.5, 0.5, -0.08), radius=0.04),))
    lists = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, edge_radius=(0.02,) * 20,
                                                              edge_youngs_modulus=(1e6,) * 20))
    out = []
    for s in (spec, lists):
        sim = Simulator(build_model(s), envs=2)
        st, c = sim.reset(), sim.make_control()
        sim.set_natural_curvature(c, [0.03, -0.02], nodes=[5, 10, 15])
        for _ in range(20):
            stats = sim.step(st, c)
        out.append((st.node_pos.copy(), stats.contact_count.copy()))
    assert out[0][1].max() > 0  # the capsule is touched
    assert np.array_equal(out[0][0], out[1][0])


def test_contact_uses_each_edge_radius():
    """A free tapered rod (radius 20 mm at one end, 5 mm at the other) settles on a floor: every node rests at its
    own radius above it (the larger of its two edges'), not at the largest radius of the rod."""
    N = 11
    r = np.linspace(0.02, 0.005, N - 1)
    spec = make_spec(nodes=N, length=1.0, radius=0.02, E=1e6, clamp="none", dt=0.01, gravity=(0.0, 0.0, -9.81),
                     start=(0.0, 0.0, 0.03), max_iter=20, accept=True, tol=1e-8, damping=5.0)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, edge_radius=tuple(r)),
                               obstacles=(PlaneSpec(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)),))
    spec = dataclasses.replace(spec, contact=dataclasses.replace(spec.contact, delta=5e-4, stiffness=1e5))
    sim = Simulator(build_model(spec), envs=1)
    st, c = sim.reset(), sim.make_control()
    for _ in range(300):
        stats = sim.step(st, c)
    assert not stats.failed.any()
    z = st.node_pos[0, :, 2]
    node_r = np.concatenate([[r[0]], np.maximum(r[:-1], r[1:]), [r[-1]]])
    np.testing.assert_allclose(z, node_r, atol=1e-3)
    assert z[-1] < 0.5 * r[0]  # the thin end lies far lower than the thick one would


_DOC = small_scene_toml("""
radius = [0.01, 0.012, 0.014, 0.016]
youngs_modulus = [1e6, 2e6, 2e6, 1e6]
""")


def test_scene_keys_round_trip_and_bad_lists_are_named():
    spec = parse_scene(tomllib.loads(_DOC))
    assert spec.rod.edge_radius == (0.01, 0.012, 0.014, 0.016) and spec.rod.radius == 0.016
    assert spec.rod.edge_youngs_modulus == (1e6, 2e6, 2e6, 1e6) and spec.rod.youngs_modulus == 2e6
    assert parse_scene(tomllib.loads(scene_to_toml(spec))) == spec
    radius_line, youngs_line = "radius = [0.01, 0.012, 0.014, 0.016]", "youngs_modulus = [1e6, 2e6, 2e6, 1e6]"
    bad = [
        (radius_line, "radius = [0.01, 0.02]",
         r"rod\.radius: a per-edge list needs one value per edge \(rod\.nodes - 1 = 4\), got 2"),
        (radius_line, "radius = [0.01, -0.02, 0.01, 0.01]", r"rod\.radius: must be > 0"),
        (youngs_line, "youngs_modulus = [1e6, 1e6, 1e6, 1e6, 1e6]",
         r"rod\.youngs_modulus: a per-edge list needs one value per edge \(rod\.nodes - 1 = 4\), got 5"),
        (radius_line, 'cross_section = "ellipse"\nsemi_axes = [0.01, 0.02]\nradius = [0.01, 0.01, 0.01, 0.01]',
         r"rod\.radius: not used by cross_section = 'ellipse'"),
    ]
    for old, new, msg in bad:
        with pytest.raises(SceneError, match=msg):
            parse_scene(tomllib.loads(_DOC.replace(old, new)))
