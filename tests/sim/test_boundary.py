"""[[load]] and [[fix]] tables (sim.scene.boundary): parsing, errors naming the key, dump round trip, constrained DOFs,
per-env load windows and prescribed motion through the Simulator."""
from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model, dump_scene, load_scene, parse_scene
from sim.scene.boundary import FixSpec, LoadSpec
from sim.scene.spec import SceneError, scene_to_toml
from tests.helpers.rodspec import make_spec

BASE = """
[sim]
dt = 0.01
gravity = [0.0, 0.0, 0.0]
newton_tol = 1e-8
newton_max_iter = 30
accept_unconverged = false
[rod]
nodes = 11
length = 1.0
radius = 0.02
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.5
start = [0.0, 0.0, 0.0]
direction = [1.0, 0.0, 0.0]
clamp = "none"
"""


def _scene(extra: str):
    return parse_scene(tomllib.loads(BASE + extra), "s.toml")


def test_load_and_fix_tables_parse_and_constrain_dofs():
    spec = _scene("""
[[fix]]
nodes = [0, -1]
axes = "xz"
twist_edges = [0]
[[load]]
node = -1
force = [0.0, 0.0, -2.0]
torque = 0.5
start = 0.1
stop = 0.3
""")
    assert spec.fixes == (FixSpec(nodes=(0, -1), axes="xz", twist_edges=(0,)),)
    assert spec.loads == (LoadSpec(node=-1, force=(0.0, 0.0, -2.0), torque=0.5, start=0.1, stop=0.3),)
    m = build_model(spec)
    fixed = m.dof_fixed.reshape(11, 4)
    assert fixed[0].tolist() == [True, False, True, True] and fixed[10].tolist() == [True, False, True, True]
    assert not fixed[1:10, :3].any()
    F = m.load_force.reshape(1, 11, 4)
    assert F[0, 10, 2] == -2.0 and F[0, 9, 3] == 0.5 and np.count_nonzero(F) == 2  # torque on the last edge
    assert m.load_window.tolist() == [[0.1, 0.3]]


@pytest.mark.parametrize("extra, key", [
    ("[[load]]\nnode = 11\nforce = [1.0, 0.0, 0.0]\n", "load[0].node"),
    ("[[load]]\nnode = 0\nforce = [1.0, 0.0]\n", "load[0].force"),
    ("[[load]]\nnode = 0\nforce = [1e12, 0.0, 0.0]\n", "load[0].force"),
    ("[[load]]\nnode = 0\nstart = 1.0\nstop = 0.5\n", "load[0].stop"),
    ("[[load]]\nnode = 0\nrod = \"arm\"\n", "load[0].rod"),
    ("[[load]]\nnode = 0\nforse = [1.0, 0.0, 0.0]\n", "load[0].forse"),
    ("[[fix]]\nnodes = [0]\naxes = \"xw\"\n", "fix[0].axes"),
    ("[[fix]]\nnodes = [-12]\n", "fix[0].nodes"),
    ("[[fix]]\nnodes = [0.5]\n", "fix[0].nodes"),
    ("[[fix]]\ntwist_edges = [10]\n", "fix[0].twist_edges"),
    ("[[fix]]\nnodes = [0]\naxes = \"x\"\nvelocity = [0.0, 1.0, 0.0]\n", "fix[0].velocity"),
    ("[[fix]]\nnodes = [0]\ntwist_rate = 1.0\n", "fix[0].twist_rate"),
    ("[[fix]]\naxes = \"x\"\n", "fix[0].nodes"),
    ("[fix]\nnodes = [0]\n", "fix"),
    ("[[load]]\nnode = 0\nmoment = [0.0, 1e12, 0.0]\n", "load[0].moment"),
    ("[[load]]\nnode = 0\nframe = \"body\"\n", "load[0].frame"),
    ("[[line_load]]\nforce_per_length = [0.0, 0.0, 1e12]\n", "line_load[0].force_per_length"),
    ("[[line_load]]\nnode = 3\n", "line_load[0].node"),
    ("[[line_load]]\nrod = \"arm\"\n", "line_load[0].rod"),
])
def test_bad_boundary_input_names_the_key(extra, key):
    with pytest.raises(SceneError) as ei:
        _scene(extra)
    assert f"s.toml: {key}" in str(ei.value)


def test_planar_scene_rejects_twist_keys():
    assert _scene("[[load]]\nnode = 0\ntorque = 1.0\n").loads[0].torque == 1.0  # 3-D: fine
    with pytest.raises(SceneError, match="load\\[0\\].torque"):
        parse_scene(tomllib.loads(BASE.replace("dt = 0.01", "dt = 0.01\nmode = \"2d\"")
                                  + "[[load]]\nnode = 0\ntorque = 1.0\n"), "s.toml")
    with pytest.raises(SceneError, match="fix\\[0\\].twist_edges"):
        parse_scene(tomllib.loads(BASE.replace("dt = 0.01", "dt = 0.01\nmode = \"2d\"")
                                  + "[[fix]]\ntwist_edges = [0]\n"), "s.toml")
    planar = BASE.replace("dt = 0.01", "dt = 0.01\nmode = \"2d\"")
    assert parse_scene(tomllib.loads(planar + "[[load]]\nnode = 0\nmoment = [0.0, 2.0, 0.0]\n")).loads[0].moment[1] == 2
    with pytest.raises(SceneError, match="load\\[0\\].moment: mode '2d' bends in the x-z plane"):
        parse_scene(tomllib.loads(planar + "[[load]]\nnode = 0\nmoment = [1.0, 0.0, 0.0]\n"), "s.toml")
    with pytest.raises(SceneError, match="load\\[0\\].frame: material-frame"):
        parse_scene(tomllib.loads(planar + "[[load]]\nnode = 0\nframe = \"material\"\n"), "s.toml")
    with pytest.raises(SceneError, match="line_load\\[0\\].force_per_length: mode '2d'"):
        parse_scene(tomllib.loads(planar + "[[line_load]]\nforce_per_length = [0.0, 1.0, 0.0]\n"), "s.toml")


def test_boundary_tables_round_trip(tmp_path):
    spec = _scene("""
[[fix]]
rod = "rod"
nodes = [0, 1]
velocity = [0.0, 0.0, 0.25]
start = 0.5
stop = 1.5
[[fix]]
twist_edges = [-1]
twist_rate = 2.0
[[load]]
node = 5
force = [0.0, 1.0, 0.0]
[[load]]
node = -1
force = [0.0, 0.5, 0.0]
moment = [0.0, 0.0, 0.1]
frame = "material"
[[line_load]]
force_per_length = [0.0, 0.0, -2.0]
stop = 3.0
""")
    out = tmp_path / "b.toml"
    dump_scene(spec, out)
    back = load_scene(out)
    assert back.fixes == spec.fixes and back.loads == spec.loads and back.line_loads == spec.line_loads
    assert len(back.line_loads) == 1 and back.loads[1].frame == "material"
    assert scene_to_toml(back) == out.read_text()


def test_api_specs_are_checked_by_build_model():
    spec = dataclasses.replace(make_spec(), loads=(LoadSpec(node=40),))
    with pytest.raises(SceneError, match="load\\[0\\].node"):
        build_model(spec)


def test_load_window_acts_per_env():
    """Two envs at different times: the load acts only in the env whose step lies in its window; a step that
    straddles the window's end gets the force weighted by the fraction inside."""
    spec = dataclasses.replace(make_spec(clamp="none", dt=0.01),
                               loads=(LoadSpec(node=5, force=(0.0, 0.0, 3.0), start=1.0, stop=1.005),))
    sim = Simulator(build_model(spec), envs=3)
    state, ctrl = sim.reset(), sim.make_control()
    state.time[:] = [0.0, 1.0, 0.5]
    sim.step(state, ctrl)
    m = sim.model
    # momentum: Σ m v_z = F · (fraction of the step in the window) · dt
    p = (state.dof_vel[:, :, 2] * m.node_mass[None, :]).sum(axis=1)
    assert abs(p[0]) < 1e-12 and abs(p[2]) < 1e-12
    assert p[1] == pytest.approx(3.0 * 0.5 * 0.01, rel=1e-8)


def test_prescribed_motion_and_twist_rate():
    """Fixed nodes follow velocity × (time in window) exactly, with that velocity; a fixed edge twists at its
    rate; the window closes at stop."""
    spec = dataclasses.replace(
        make_spec(clamp="none", dt=0.01, damping=5.0),
        fixes=(FixSpec(nodes=(0, 1), velocity=(0.0, 0.0, 0.2), stop=0.105),
               FixSpec(twist_edges=(0,), twist_rate=3.0, stop=0.105)))
    sim = Simulator(build_model(spec), envs=2)
    state, ctrl = sim.reset(), sim.make_control()
    state.time[1] = 0.05  # the second env starts later in the window: it moves less
    x0 = state.dof[:, :2, :3].copy()
    for k in range(8):
        sim.step(state, ctrl)
        assert not state.failed.any()
        t = state.time
        moved = 0.2 * np.clip(np.minimum(t, 0.105) - np.array([0.0, 0.05]), 0, None)
        assert np.allclose(state.dof[:, :2, 2] - x0[:, :, 2], moved[:, None], atol=1e-14)
        assert np.allclose(state.dof[:, :2, :2], x0[:, :, :2], atol=0)
        frac = np.clip((np.minimum(t, 0.105) - np.maximum(t - 0.01, [0.0, 0.05])) / 0.01, 0.0, 1.0)
        assert np.allclose(state.dof_vel[:, :2, 2], 0.2 * frac[:, None], atol=1e-12)
        assert np.allclose(state.dof[:, 0, 3], moved / 0.2 * 3.0, atol=1e-12)
    for _ in range(4):
        sim.step(state, ctrl)
    assert np.allclose(state.dof[:, 0, 2], 0.2 * np.array([0.105, 0.055]), atol=1e-14)
    assert np.allclose(state.dof_vel[:, :2, 2], 0.0, atol=1e-14)


def test_prescribed_motion_planar():
    """2-D: a pinned end (axes "xz") carried along z; the other end stays pinned; y (the plane) is not a DOF."""
    spec = dataclasses.replace(
        make_spec(clamp="none", dt=0.01, mode="2d", damping=5.0),
        fixes=(FixSpec(nodes=(0,), axes="xz", velocity=(0.0, 0.0, 0.3)), FixSpec(nodes=(-1,), axes="xyz")))
    m = build_model(spec)
    assert m.dof_fixed.reshape(11, 2)[[0, -1]].all() and not m.dof_fixed.reshape(11, 2)[1:-1].any()
    sim = Simulator(m, envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    for k in range(1, 6):
        sim.step(state, ctrl)
        assert not state.failed.any()
        assert state.dof[0, 0].tolist() == pytest.approx([0.0, 0.3 * 0.01 * k], abs=1e-14)
        assert state.dof_vel[0, 0].tolist() == pytest.approx([0.0, 0.3], abs=1e-12)
        assert state.dof[0, -1].tolist() == pytest.approx([1.0, 0.0], abs=1e-14)


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_control_force_is_a_point_load_for_one_step(mode):
    """Control.force on a node acts as a [[load]] of the same force does (same trajectory to round-off), per env:
    an env without force does not move, and in 2-D the y component is ignored."""
    F = (0.5, 0.7 if mode == "3d" else 0.0, -2.0)
    base = make_spec(clamp="first_edge", dt=0.01, mode=mode)
    loaded = Simulator(build_model(dataclasses.replace(base, loads=(LoadSpec(node=-1, force=F),))), envs=1)
    pulled = Simulator(build_model(base), envs=2)
    s1, c1 = loaded.reset(), loaded.make_control()
    s2, c2 = pulled.reset(), pulled.make_control()
    c2.force = np.zeros((2, pulled.model.node_count, 3))
    c2.force[0, -1] = F
    c2.force[1, -1] = (0.0, 9.0, 0.0) if mode == "2d" else (0.0, 0.0, 0.0)  # the plane's normal: no effect in 2-D
    for _ in range(20):
        loaded.step(s1, c1)
        st = pulled.step(s2, c2)
    assert st.converged.all()
    np.testing.assert_allclose(s2.dof[0], s1.dof[0], rtol=0, atol=1e-12)
    assert np.abs(s2.dof[1] - pulled.reset().dof[1]).max() < 1e-12
    assert np.abs(s2.dof[0] - pulled.reset().dof[0]).max() > 1e-3  # it did move the rod


def test_control_force_is_checked():
    sim = Simulator(build_model(make_spec()), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    ctrl.force = np.zeros((1, 3, 3))
    with pytest.raises(ValueError, match=r"ctrl.force: expected shape \(1, 11, 3\)"):
        sim.step(state, ctrl)
    ctrl.force = np.zeros((1, 11, 3))
    ctrl.force[0, 4, 1] = np.nan
    with pytest.raises(ValueError, match="ctrl.force: contains NaN"):
        sim.step(state, ctrl)
