"""rest_points (non-straight rest shapes): parsing, errors naming the key, dump round trip, the Model's rest
geometry; and a rod released at its curved rest shape stays at rest (docs/physics.md §1.2, §8D)."""
from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model, dump_scene, load_scene, parse_scene
from sim.scene.spec import SceneError, rest_shape_fields
from tests.helpers.rodspec import make_spec

HEAD = """
[sim]
dt = 0.01
gravity = [0.0, 0.0, 0.0]
newton_tol = 1e-10
newton_max_iter = 30
accept_unconverged = false
{mode}
[rod]
radius = 0.01
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.5
clamp = "none"
"""


def helix(N=41, R=0.1, pitch=0.05, turns=2.0):
    s = np.linspace(0.0, 2 * np.pi * turns, N)
    return np.stack([R * np.cos(s), R * np.sin(s), pitch * s / (2 * np.pi)], axis=1)


def _scene(points, extra="", mode=""):
    pts = ", ".join("[" + ", ".join(repr(float(c)) for c in p) + "]" for p in points)
    return parse_scene(tomllib.loads(HEAD.format(mode=mode) + f"rest_points = [{pts}]\n" + extra), "s.toml")


def test_rest_points_give_the_rest_geometry(tmp_path):
    P = helix()
    spec = _scene(P)
    r = spec.rod
    assert r.nodes == 41 and r.start == tuple(P[0]) and r.rest_points[5] == tuple(P[5])
    assert r.length == pytest.approx(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
    m = build_model(spec)
    assert np.array_equal(m.rest_node_pos, P)
    assert np.allclose(m.rest_edge_length, np.linalg.norm(np.diff(P, axis=0), axis=1))
    # a helix has the same curvature magnitude at every interior node, and the rest shape carries it
    kmag = np.linalg.norm(m.rest_kappa_bar[1:-1], axis=1)
    assert kmag.min() > 0.05 and np.ptp(kmag) < 1e-9 * kmag.max()
    dump_scene(spec, tmp_path / "h.toml")
    back = load_scene(tmp_path / "h.toml")
    assert back.rod == spec.rod
    assert "start" not in tomllib.loads((tmp_path / "h.toml").read_text())["rod"]


@pytest.mark.parametrize("points, extra, mode, match", [
    ([[0, 0, 0], [1, 0, 0]], "", "", "rod.rest_points: expected a list of at least 3"),
    ([[0, 0, 0], [1, 0, 0], [1, 0, 0]], "", "", "rod.rest_points: consecutive points"),
    ([[0, 0, 0], [1, 0, 0], [0.01, 0.0, 0.001]], "", "", "rod.rest_points: the polyline turns by"),
    ([[0, 0, 0], [1, 0, 0], [2, 0, 1e7]], "", "", "rod.rest_points"),
    ([[0, 0, 0], [1, 0, 0], [2, 0, 1]], "nodes = 3\n", "", "rod.nodes: not used with rest_points"),
    ([[0, 0, 0], [1, 0, 0], [2, 0.1, 1]], "", 'mode = "2d"', "rod.rest_points: mode '2d'"),
])
def test_bad_rest_points_name_the_key(points, extra, mode, match):
    with pytest.raises(SceneError, match=match):
        _scene(np.asarray(points, dtype=float), extra, mode)


def test_api_rest_points_must_match_nodes():
    spec = make_spec(nodes=11)
    bad = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, rest_points=tuple(map(tuple, helix(9)))))
    with pytest.raises(SceneError, match="rod.rest_points: expected rod.nodes = 11 points"):
        build_model(bad)
    ok = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, **rest_shape_fields(helix(9))))
    assert build_model(ok).node_count == 9


@pytest.mark.parametrize("integrator", ["backward_euler", "midpoint"])
def test_helix_released_at_rest_stays_at_rest(integrator):
    """No gravity, free ends: the helical rest shape is an equilibrium (no spurious force), so over 300 steps the
    velocities stay at round-off and the nodes where they were."""
    spec = _scene(helix())
    spec = dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, integrator=integrator))
    sim = Simulator(build_model(spec), envs=2)
    state, ctrl = sim.reset(), sim.make_control()
    for _ in range(300):
        stats = sim.step(state, ctrl)
        assert not stats.failed.any()
    assert np.abs(state.dof_vel).max() < 1e-9
    assert np.abs(state.node_pos - sim.model.rest_node_pos[None]).max() < 1e-10
    assert (stats.energy_bend + stats.energy_twist + stats.energy_stretch).max() < 1e-20


def test_planar_arc_released_at_rest_stays_at_rest():
    a = np.linspace(0.0, 2.0, 31)
    arc = np.stack([0.3 * np.sin(a), np.zeros_like(a), 0.3 * (1 - np.cos(a))], axis=1)
    for mode in ('mode = "2d"', ""):
        sim = Simulator(build_model(_scene(arc, mode=mode)), envs=1)
        state, ctrl = sim.reset(), sim.make_control()
        for _ in range(200):
            assert not sim.step(state, ctrl).failed.any()
        assert np.abs(state.dof_vel).max() < 1e-9
        assert np.abs(state.node_pos[0] - arc).max() < 1e-10
