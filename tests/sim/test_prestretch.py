"""Pre-stretch (``[rod] prestretch = ε0``; docs/physics.md §1.2): the rest edge lengths are the initial ones over
1 + ε0. A taut string (a thin rod pinned at both ends) under a midspan load against the string formula
δ = F L / (4 T) with T = E A ε0, a free rod relaxing to its rest length, the scene key's bounds and round trip."""
from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model
from sim.scene.boundary import FixSpec, LoadSpec
from sim.scene.spec import parse_scene, scene_to_toml
from sim.scene.tomlio import SceneError
from tests.helpers.rodspec import make_spec, small_scene_toml
from tests.helpers.statics import static_solve

E, R, EPS0 = 1e7, 0.002, 0.05


def _with_prestretch(spec, eps0):
    return dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, prestretch=eps0))


def test_rest_lengths_masses_and_initial_strain():
    spec = _with_prestretch(make_spec(nodes=11, length=1.0, radius=R, E=E, density=1000.0), EPS0)
    m = build_model(spec)
    np.testing.assert_allclose(m.rest_edge_length, 0.1 / (1 + EPS0), rtol=1e-12)
    # the material's mass: ρ A times the rest length
    np.testing.assert_allclose(m.node_mass.sum(), 1000.0 * np.pi * R ** 2 / (1 + EPS0), rtol=1e-12)
    sim = Simulator(m, envs=1)
    st = sim.reset()
    e = np.linalg.norm(np.diff(st.node_pos[0], axis=0), axis=1)
    np.testing.assert_allclose(e / m.rest_edge_length - 1.0, EPS0, rtol=1e-12)
    # held at both ends the straight stretched rod is in equilibrium: it keeps its strain and stretching energy
    held = dataclasses.replace(spec, fixes=(FixSpec(nodes=(0, -1), axes="xyz"),))
    sim = Simulator(build_model(held), envs=1)
    st = sim.reset()
    stats = sim.step(st, sim.make_control())
    np.testing.assert_allclose(stats.energy_stretch[0], 0.5 * m.EA_max * EPS0 ** 2 * m.rest_edge_length.sum(),
                               rtol=1e-9)


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_taut_string_under_a_midspan_load(mode):
    """A 4 mm rod pinned at both ends with 5 % pre-stretch is a string of tension T = E A ε0 = 6.28 N (bending adds
    about 0.03 % of stiffness): a midspan load F sags it by F L/(4 T)."""
    N, F = 21, 0.01
    spec = make_spec(nodes=N, length=1.0, radius=R, E=E, clamp="none", dt=1e4, dtol=1e-14, max_iter=100, mode=mode)
    twist = (0,) if mode == "3d" else ()
    spec = dataclasses.replace(_with_prestretch(spec, EPS0),
                               fixes=(FixSpec(nodes=(0, -1), axes="xyz", twist_edges=twist),),
                               loads=(LoadSpec(node=N // 2, force=(0.0, 0.0, -F)),))
    sim, state, stats = static_solve(spec, steps=4)
    assert stats.converged.all()
    T = E * np.pi * R ** 2 * EPS0
    sag = -state.node_pos[0, N // 2, 2]
    assert sag == pytest.approx(F * 1.0 / (4 * T), rel=2e-3)
    # without the pre-stretch the same rod is a soft beam that sags orders of magnitude more
    loose = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, prestretch=0.0))
    _, st2, _ = static_solve(loose, steps=4)
    assert -st2.node_pos[0, N // 2, 2] > 20 * sag


def test_free_rod_relaxes_to_its_rest_length():
    spec = make_spec(nodes=11, length=1.0, radius=0.01, E=1e6, clamp="none", dt=0.01, damping=20.0, max_iter=20,
                     tol=1e-10)
    sim = Simulator(build_model(_with_prestretch(spec, 0.2)), envs=1)
    st, c = sim.reset(), sim.make_control()
    for _ in range(300):
        stats = sim.step(st, c)
    assert not stats.failed.any()
    x = st.node_pos[0]
    assert np.linalg.norm(x[-1] - x[0]) == pytest.approx(1.0 / 1.2, rel=1e-6)


_DOC = small_scene_toml("""
prestretch = 0.05
""")


def test_scene_key_round_trip_and_bounds():
    spec = parse_scene(tomllib.loads(_DOC))
    assert spec.rod.prestretch == 0.05
    assert parse_scene(tomllib.loads(scene_to_toml(spec))) == spec
    assert "prestretch" not in scene_to_toml(_with_prestretch(spec, 0.0))
    for bad in ("0.7", "-0.6", '"a lot"'):
        with pytest.raises(SceneError, match=r"rod\.prestretch"):
            parse_scene(tomllib.loads(_DOC.replace("prestretch = 0.05", f"prestretch = {bad}")))
