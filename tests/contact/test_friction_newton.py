"""Friction under the default Newton settings (line_search = "auto"): the stick regime converges, a rod on an
incline creeps no faster than the regularised stick law allows, resting contact forces balance the weight,
and a cantilever resting on a sphere keeps a steady friction force (docs/physics.md, friction)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sim import Simulator, build_model, parse_scene

R = 0.01
ROD = dict(nodes=11, length=0.5, radius=R, density=1000.0, youngs_modulus=1e7, poisson_ratio=0.5,
           start=[0.0, 0.0, 0.0], direction=[1.0, 0.0, 0.0], clamp="none")
NU = 1e-2  # friction_velocity_tol (the [contact] default)


def make(rod, obstacles, contact, **sim_kw):
    """Scene with the default Newton settings except those given (no line_search key: the default)."""
    s = dict(dt=0.01, gravity=[0.0, 0.0, -9.8], newton_tol=1e-6, newton_max_iter=10, accept_unconverged=True)
    s.update(sim_kw)
    doc = {"sim": s, "rod": dict(rod), "obstacle": [dict(o) for o in obstacles], "contact": dict(contact)}
    sim = Simulator(build_model(parse_scene(doc, None)), envs=1)
    return sim, sim.reset(), sim.make_control()


def net_contact_force(s):
    k = int(s.contact_count[0])
    return (s.contact_normal_force[0, :k, None] * s.contact_normal[0, :k]).sum(0) + \
        s.contact_friction_force[0, :k].sum(0)


def test_free_rod_on_incline_sticks_with_regularised_creep():
    """20° incline, μ = 0.5 (friction angle 26.6°): the rod must stick. The smooth stick law
    γ = tanh(15|v_t|/(2ν)) holds the slope load μ N γ = m g sin α only with the creep velocity
    v_c = (2ν/15) artanh(tan α / μ) = 1.233e-3 m/s down the slope, so over T = 1 s the rod may move at most
    v_c T plus the slide while the normal force builds up on landing (< 1 mm), and never up the slope."""
    a = math.radians(20.0)
    n = np.array([-math.sin(a), 0.0, math.cos(a)])
    up = np.array([math.cos(a), 0.0, math.sin(a)])
    lift = R + 4e-3  # released just inside the contact layer (gap 4 mm < delta), at rest
    rod = dict(ROD, start=list(lift * n), direction=[0.0, 1.0, 0.0])
    sim, st, ctrl = make(rod, [dict(type="plane", point=[0, 0, 0], normal=list(n))], dict(friction=0.5))
    x0 = st.node_pos[0].copy()
    conv = []
    for _ in range(100):
        conv.append(bool(sim.step(st, ctrl).converged[0]))
    disp = float(np.mean((st.node_pos[0] - x0) @ up))
    v_creep = (2.0 * NU / 15.0) * math.atanh(math.tan(a) / 0.5)
    assert all(conv)
    assert -(v_creep * 1.0 + 1e-3) <= disp <= 0.0, disp
    v = float(np.mean(st.node_vel[0] @ up))
    assert v == pytest.approx(-v_creep, rel=0.05)  # the settled creep is the regularised one


def test_free_rod_on_two_capsules_forces_balance_weight():
    """A free rod settled (light damping) on two parallel capsules, μ = 0.5: the reported contact forces
    (normal + friction) sum to the rod's weight to 1e-6 relative, and Newton converges every late step."""
    rod = dict(ROD, start=[0.0, 0.0, R + 4e-3])
    caps = [dict(type="capsule", start=[x, -0.2, -0.02], end=[x, 0.2, -0.02], radius=0.02) for x in (0.1, 0.42)]
    sim, st, ctrl = make(rod, caps, dict(friction=0.5), damping=5.0)
    W = float(sim.model.node_mass.sum() * 9.8)
    for i in range(300):
        s = sim.step(st, ctrl)
        if i >= 200:
            assert s.converged[0]
    F = net_contact_force(s)
    assert int(s.contact_count[0]) == 2
    assert abs(F[2] / W - 1.0) < 1e-6, F[2] / W - 1.0
    assert np.hypot(F[0], F[1]) < 1e-5 * W  # friction holds the normals' horizontal parts
    assert s.max_penetration[0] < 5e-3


def test_cantilever_on_sphere_friction_does_not_cycle():
    """A clamped cantilever sagging onto a sphere, μ = 0.5: once in contact every step converges, the friction
    force keeps its direction and stays within the Coulomb cone (|f_t| ≤ μ N); without a globally convergent
    Newton it swung between ±μN from step to step."""
    rod = dict(ROD, nodes=21, length=1.0, clamp="first_edge")
    sim, st, ctrl = make(rod, [dict(type="sphere", center=[0.8, 0.0, -0.1 - R - 0.002], radius=0.1)],
                         dict(friction=0.5))
    fx, fn, conv = [], [], []
    for i in range(200):
        s = sim.step(st, ctrl)
        if i >= 100:
            k = int(s.contact_count[0])
            assert k >= 1
            fx.append(float(s.contact_friction_force[0, :k].sum(0)[0]))
            fn.append(float(s.contact_normal_force[0, :k].sum()))
            conv.append(bool(s.converged[0]))
            ft = float(np.linalg.norm(s.contact_friction_force[0, :k].sum(0)))
            assert ft <= 0.5 * fn[-1] * (1 + 1e-9)
    fx, fn = np.array(fx), np.array(fn)
    assert all(conv)
    assert np.all(np.sign(fx) == np.sign(fx[0]))
    assert np.ptp(fx) < 0.25 * 0.5 * fn.mean()


def test_per_obstacle_friction_overrides_contact_default():
    """`friction` in an [[obstacle]] table replaces the [contact] μ for that obstacle only: on a 20° incline
    a plane with μ = 0.1 lets the rod slide (a = g (sin α − μ cos α)) although [contact] says μ = 0.5."""
    a = math.radians(20.0)
    n = np.array([-math.sin(a), 0.0, math.cos(a)])
    up = np.array([math.cos(a), 0.0, math.sin(a)])
    rod = dict(ROD, start=list((R + 4e-3) * n), direction=[0.0, 1.0, 0.0])
    plane = dict(type="plane", point=[0, 0, 0], normal=list(n), friction=0.1)
    sim, st, ctrl = make(rod, [plane], dict(friction=0.5))
    assert sim.model.obstacles.effective_friction(0.5).tolist() == [0.1]
    for _ in range(100):
        sim.step(st, ctrl)
    v = float(np.mean(st.node_vel[0] @ up))
    expect = -9.8 * (math.sin(a) - 0.1 * math.cos(a)) * 1.0
    assert v == pytest.approx(expect, rel=0.05)
