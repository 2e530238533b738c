"""Viscous drag per unit length (resistive-force theory, docs/physics.md §3.1) against closed forms: the decay of a
free rod's velocity under the backward-Euler step, the terminal velocity of a rod sedimenting across, along and at
an angle to gravity, a clamped rod in a uniform cross-flow (a line load by another name, and q L⁴/8EI), energy
only removed without a flow; the [drag] table's round trip and checks."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim import Simulator, build_model, parse_scene
from sim.analysis.static import solve_static
from sim.scene.boundary import DragSpec, LineLoadSpec
from sim.scene.spec import SceneError, scene_to_toml
from tests.helpers.rodspec import make_spec

R, E, L = 0.01, 1e6, 0.5
CT = 2.0           # tangential coefficient [N s/m²]
CN = 2.0 * CT      # normal: slender-body theory's c_n ≈ 2 c_t


def _free_rod(direction, mode="3d", drag=DragSpec(normal=CN, tangential=CT), gravity=(0.0, 0.0, -9.81), dt=0.01,
              nodes=11):
    spec = make_spec(nodes=nodes, length=L, radius=R, E=E, clamp="none", direction=direction, gravity=gravity,
                     dt=dt, mode=mode)
    spec = dataclasses.replace(spec, drag=drag)
    sim = Simulator(build_model(spec), envs=1)
    return sim, sim.reset(), sim.make_control()


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_free_rod_velocity_decays_as_the_implicit_step_says(mode):
    """A straight free rod moving across itself at v0, no gravity: every node feels m_i/h (v' − v) = −c_n l_i v' with
    m_i ∝ l_i, so the backward-Euler step gives v_n = v0 / (1 + h c_n L/m)^n exactly, and the rod stays straight."""
    sim, st, ctrl = _free_rod((1.0, 0.0, 0.0), mode=mode, gravity=(0.0, 0.0, 0.0))
    m = float(sim.model.node_mass.sum())
    h = sim.model.dt
    st.dof_vel[0, :, -1 if mode == "2d" else 2] = 0.3        # along z, across the rod
    x0 = st.node_pos[0].copy()
    for n in range(1, 21):
        sim.step(st, ctrl)
        v = st.node_vel[0, :, 2]
        np.testing.assert_allclose(v, 0.3 / (1.0 + h * CN * L / m) ** n, rtol=1e-10)
    np.testing.assert_allclose(st.node_pos[0, :, 0], x0[:, 0], atol=1e-12)


@pytest.mark.parametrize("angle_deg", [0.0, 90.0, 45.0, 30.0])
def test_sedimenting_rod_reaches_the_resistive_force_theory_velocity(angle_deg):
    """A free straight rod at an angle φ to the horizontal sinks under its weight W at the terminal velocity
    V = (1/L)[t̂t̂ᵀ/c_t + (I − t̂t̂ᵀ)/c_n] W: across (φ = 0) at W/(c_n L), along (φ = 90°) at W/(c_t L) and, oblique,
    gliding sideways (at c_n = 2 c_t and 45°, at one third of its sinking speed), without turning."""
    a = math.radians(angle_deg)
    t = np.array([math.cos(a), 0.0, math.sin(a)])
    sim, st, ctrl = _free_rod(tuple(t))
    W = np.array([0.0, 0.0, -9.81 * float(sim.model.node_mass.sum())])
    for _ in range(400):                                   # 4 s: ≈ 25 time constants m/(c_t L)
        s = sim.step(st, ctrl)
        assert s.converged[0]
    V = (np.outer(t, t) / CT + (np.eye(3) - np.outer(t, t)) / CN) @ W / L
    np.testing.assert_allclose(st.node_vel[0], np.broadcast_to(V, (11, 3)), rtol=1e-6, atol=1e-9)
    p = st.node_pos[0]
    e = (p[-1] - p[0]) / np.linalg.norm(p[-1] - p[0])
    assert np.dot(e, t) > 1.0 - 1e-9                       # no turning: the drag's centre is the centre of mass
    if angle_deg == 45.0:
        v = st.node_vel[0, 0]                              # down along its own axis: sideways at 1/3 of its sinking
        assert v[0] / v[2] == pytest.approx(1.0 / 3.0, rel=1e-6)


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_clamped_rod_in_a_cross_flow_is_a_cantilever_under_a_line_load(mode):
    """A cantilever in a uniform cross-flow U, at rest: isotropic drag c gives node forces l_i c U, the line load
    q = c U by another name (the same static shape to 1e-12); with c_n = 2 c_t only the normal part c_n U pushes
    a nearly straight rod, and its tip deflects by q L⁴/(8EI) (free length from the middle of the clamped edge)."""
    U = 0.02
    base = make_spec(nodes=21, length=1.0, radius=0.02, E=1e7, dt=1e4, dtol=1e-14, max_iter=100, mode=mode)

    def relaxed(spec):
        sim = Simulator(build_model(spec), envs=1)
        st, ctrl = sim.reset(), sim.make_control()
        res = solve_static(spec, st, ctrl, xtol=1e-13, check_stability=False, max_steps=400)
        assert res.converged.all()
        return sim, st.node_pos[0]

    _, a = relaxed(dataclasses.replace(base, drag=DragSpec(normal=CN, tangential=CN, flow=(0.0, 0.0, U))))
    sim, b = relaxed(dataclasses.replace(base, line_loads=(LineLoadSpec(force_per_length=(0.0, 0.0, CN * U)),)))
    np.testing.assert_allclose(a, b, atol=1e-12)
    _, c = relaxed(dataclasses.replace(base, drag=DragSpec(normal=CN, tangential=CT, flow=(0.0, 0.0, U))))
    Lf = 1.0 - 0.5 * sim.model.rest_edge_length[0]
    expect = CN * U * Lf ** 4 / (8 * sim.model.EI1_max)
    assert c[-1, 2] - 0.5 * (c[0, 2] + c[1, 2]) == pytest.approx(expect, rel=2e-2)
    assert np.max(np.abs(c[:, 2] - b[:, 2])) < 1e-3 * np.max(np.abs(b[:, 2]))  # c_t barely enters


def test_drag_only_removes_energy_without_a_flow():
    """A free rod bent out of its rest shape and released, no gravity: with drag its elastic plus kinetic energy
    falls at every step and ends below the same rod's without drag (backward Euler's own dissipation)."""
    def run(drag):
        sim, st, ctrl = _free_rod((1.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0), drag=drag, nodes=21)
        st.dof_vel[0, :, 2] = 0.5 * np.sin(np.linspace(0.0, 2 * np.pi, 21))
        st.dof_vel[0, :, 1] = 0.3 * np.cos(np.linspace(0.0, np.pi, 21))
        out = []
        for _ in range(100):
            s = sim.step(st, ctrl)
            out.append(float(s.energy_kinetic[0] + s.energy_stretch[0] + s.energy_bend[0] + s.energy_twist[0]))
        return np.array(out)
    with_drag = run(DragSpec(normal=CN, tangential=CT))
    without = run(None)
    assert np.all(np.diff(with_drag) <= 1e-12)
    assert with_drag[-1] < 0.5 * without[-1]


def test_drag_table_round_trip_and_checks():
    doc = {"sim": dict(dt=0.01, gravity=[0, 0, -9.81], newton_tol=1e-8, newton_max_iter=20, accept_unconverged=False),
           "rod": dict(nodes=5, length=1.0, radius=0.01, density=1000.0, youngs_modulus=1e6, poisson_ratio=0.5,
                       start=[0, 0, 0], direction=[1, 0, 0]),
           "drag": dict(normal=1.5, tangential=0.75, flow=[0.1, 0.0, -0.2])}
    spec = parse_scene(doc)
    assert spec.drag == DragSpec(normal=1.5, tangential=0.75, flow=(0.1, 0.0, -0.2))
    import tomllib
    again = parse_scene(tomllib.loads(scene_to_toml(spec)))
    assert again.drag == spec.drag
    assert parse_scene({k: v for k, v in doc.items() if k != "drag"}).drag is None
    for bad, msg in [(dict(normal=-1.0), "drag.normal"), (dict(tangential=float("nan")), "drag.tangential"),
                     (dict(flow=[0, 0]), "drag.flow"), (dict(viscosity=1.0), "viscosity")]:
        with pytest.raises(SceneError, match=msg):
            parse_scene(dict(doc, drag=bad))
    planar = dict(doc, sim=dict(doc["sim"], mode="2d"), drag=dict(normal=1.0, flow=[0.0, 0.1, 0.0]))
    with pytest.raises(SceneError, match="x-z plane"):
        parse_scene(planar)
