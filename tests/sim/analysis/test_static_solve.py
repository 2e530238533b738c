"""Static equilibrium solve (sim.analysis.static, ``rodlab sim --static``; docs/physics.md §3.8, §8D): a heavy rope pinned
at both ends vs the elastic catenary, and the tip-loaded cantilever of tests/sim/test_loads.py."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

from sim import Simulator, build_model, load_scene
from sim.analysis.static import solve_static
from sim.cli import sim_main
from sim.geometry.frames import initial_reference_frames
from sim.scene.boundary import FixSpec, LoadSpec
from sim.scene.spec import dump_scene
from tests.helpers.rodspec import make_spec
from tests.helpers.statics import elastica_tip

RHO, R, G, L0, SPAN, EPS = 1000.0, 1e-3, 9.8, 1.2, 1.0, 1e-2


def elastic_catenary(s, w, EA, L0=L0, SPAN=SPAN):
    """Shape (x(s), z(s)) of an elastic cable of unstretched length L0, weight w per unstretched length and axial
    stiffness EA hanging between (0, 0) and (SPAN, 0), at unstretched arc length s. Tension (H, w s − V) with
    V = w L0/2; stretched length element (1 + T/EA) ds. H from x(L0) = SPAN (brentq)."""
    V = 0.5 * w * L0

    def xz(s, H):
        T = np.hypot(H, w * s - V)
        x = H * s / EA + H / w * (np.arcsinh((w * s - V) / H) + np.arcsinh(V / H))
        z = (w * s * s / 2 - V * s) / EA + (T - np.hypot(H, V)) / w
        return x, z

    H = brentq(lambda H: xz(L0, H)[0] - SPAN, 1e-9 * w * L0, 1e3 * w * L0, xtol=1e-15, rtol=1e-14)
    return xz(s, H)


def _rope(N):
    """A rope (bending length ~1 % of the span, axial strain ~1 %) pinned (axes only) at both ends, 1 m apart,
    starting from a circular arc of its own length; the twist of edge 0 is fixed (no zero-energy spin)."""
    E = RHO * G * L0 / EPS
    spec = make_spec(nodes=N, length=L0, radius=R, density=RHO, E=E, gravity=(0.0, 0.0, -G), clamp="none",
                     dt=1e-3, max_iter=50)
    spec = dataclasses.replace(spec, fixes=(FixSpec(nodes=(0, -1), twist_edges=(0,)),))
    sim = Simulator(build_model(spec), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    phi = brentq(lambda p: np.sin(p) / p - SPAN / L0, 1e-6, np.pi - 1e-6)
    rad = L0 / (2 * phi)
    a = np.linspace(-phi, phi, N)
    state.dof[0, :, 0] = SPAN / 2 + rad * np.sin(a)
    state.dof[0, :, 2] = rad * (np.cos(phi) - np.cos(a))
    _frames_at(sim, state)  # the stored frames of the moved nodes
    return spec, sim, state, ctrl


def _frames_at(sim, state):
    d1, t = initial_reference_frames(state.node_pos[0])
    state.edge_ref_d1[0], state.edge_tangent[0] = d1, t


@pytest.mark.parametrize("N", [21, 41])
def test_heavy_rope_vs_elastic_catenary(N):
    spec, sim, state, ctrl = _rope(N)
    res = solve_static(spec, state, ctrl)
    assert res.converged.all(), res
    m = sim.model
    s = np.concatenate([[0.0], np.cumsum(m.rest_edge_length)])
    w = RHO * np.pi * R * R * G
    x, z = elastic_catenary(s, w, m.EA_max)
    p = state.node_pos[0]
    sag = -z[N // 2]
    assert sag > 0.25  # a genuinely slack rope
    err = np.hypot(p[:, 0] - x, p[:, 2] - z).max()
    assert err < {21: 2e-3, 41: 5e-4}[N] * sag, (N, err, sag)
    assert abs(-p[N // 2, 2] - sag) < {21: 2e-3, 41: 5e-4}[N] * sag
    # the inextensible catenary would sag less: the elastic stretch is resolved
    x_in, z_in = elastic_catenary(s, w, 1e9 * m.EA_max)
    assert -z_in[N // 2] < sag - 5 * abs(-p[N // 2, 2] - sag)


def test_static_cantilever_matches_the_elastica_and_the_dynamic_relaxation():
    """The large tip load of test_loads reached by solve_static from the straight rest state."""
    EI = 1e7 * np.pi * 0.02 ** 4 / 4
    spec = make_spec(nodes=41, radius=0.02, E=1e7, dt=1e-3)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(0.0, 0.0, -3.0 * EI)),))
    sim = Simulator(build_model(spec), envs=2)
    state, ctrl = sim.reset(), sim.make_control()
    res = solve_static(spec, state, ctrl)
    assert res.converged.all() and res.steps.max() < 60
    p = state.node_pos[0]
    tip = p[-1] - 0.5 * (p[0] + p[1])
    Lf = 1.0 - 0.5 * sim.model.rest_edge_length[0]
    xt, zt = elastica_tip(3.0 * EI / sim.model.EI1_max, Lf)
    assert np.hypot(tip[0] - xt, tip[2] - zt) < 3e-3
    assert np.array_equal(state.node_pos[0], state.node_pos[1])
    assert np.all(state.time == 0.0) and np.all(state.dof_vel == 0.0)


def test_shipped_rope_scene_hangs_as_the_elastic_catenary(scenes_dir):
    """assets/scenes/rope_pinned.toml (rest shape: an arc given by rest_points, so a little rest curvature):
    midspan sag within 0.5 % of the elastic catenary of the same rope."""
    spec = load_scene(scenes_dir / "rope_pinned.toml")
    sim = Simulator(build_model(spec), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    assert solve_static(spec, state, ctrl).converged.all()
    m = sim.model
    s = np.concatenate([[0.0], np.cumsum(m.rest_edge_length)])
    w = spec.rod.density * np.pi * spec.rod.radius ** 2 * 9.8
    x, z = elastic_catenary(s, w, m.EA_max, L0=s[-1], SPAN=1.0)
    p = state.node_pos[0]
    k = spec.rod.nodes // 2
    assert abs((1.0 - p[k, 2]) - (-z[k])) < 5e-3 * -z[k], (p[k], z[k])


def test_cli_static(tmp_path, capsys):
    spec = load_scene("assets/scenes/cantilever_gravity.toml")
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(0.0, 0.0, -1.0)),))
    dump_scene(spec, tmp_path / "c.toml")
    out = tmp_path / "c.npz"
    assert sim_main([str(tmp_path / "c.toml"), "--static", "--out", str(out)]) == 0
    assert "converged envs: 1/1" in capsys.readouterr().out
    d = np.load(out)
    assert d["node_pos"].shape == (1, 1, spec.rod.nodes, 3) and d["converged"].all()
    assert d["node_pos"][0, 0, -1, 2] < -1e-3
    assert sim_main([str(tmp_path / "c.toml"), "--static", "--static-tol", "-1"]) == 2
