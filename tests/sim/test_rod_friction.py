"""Rod–rod friction (docs/physics.md §4.8): a stiff rod lying across two fixed parallel rods on a 15° incline slides
down with the Coulomb acceleration g (sin θ − μ cos θ) when μ < tan θ, and stays put (creeps below the slip
tolerance ν) when μ > tan θ."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sim import Simulator, build_model
from sim.scene.spec import parse_scene

THETA = math.radians(15.0)
G = 9.81
NU = 1e-2
DT = 0.005


def _scene(mu: float) -> dict:
    rod = {"nodes": 17, "radius": 0.01, "density": 1000.0, "youngs_modulus": 1e9, "poisson_ratio": 0.5,
           "clamp": "none"}
    return {
        "sim": {"dt": DT, "gravity": [0.0, -G * math.sin(THETA), -G * math.cos(THETA)], "damping": 0.0,
                "newton_tol": 1e-8, "newton_max_iter": 30, "accept_unconverged": False},
        # two supports along x, fixed; the plank along y rests across both (gravity tilted: the incline)
        "rod": [dict(rod, name="left", length=0.6, start=[-0.3, -0.3, 0.0], direction=[1.0, 0.0, 0.0]),
                dict(rod, name="right", length=0.6, start=[-0.3, 0.3, 0.0], direction=[1.0, 0.0, 0.0]),
                dict(rod, name="plank", nodes=25, length=1.2, start=[0.0, -0.6, 0.0205], direction=[0.0, 1.0, 0.0])],
        "fix": [{"rod": "left", "nodes": list(range(17))}, {"rod": "right", "nodes": list(range(17))}],
        "contact": {"stiffness": 1e5, "delta": 1e-3, "friction": mu, "friction_velocity_tol": NU},
    }


def _plank_velocity(mu: float, steps: int) -> np.ndarray:
    model = build_model(parse_scene(_scene(mu)))
    sim = Simulator(model, envs=1)
    st = sim.reset()
    ctrl = sim.make_control()
    a, b = model.rod_slices()["plank"].start, model.rod_slices()["plank"].stop
    v = []
    for _ in range(steps):
        stats = sim.step(st, ctrl)
        assert not stats.failed.any() and stats.converged.all()
        v.append(st.node_vel[0, a:b].mean(axis=0))
    return np.array(v)


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.2])
def test_plank_slides_with_the_coulomb_acceleration(mu):
    v = _plank_velocity(mu, 70)
    accel = (v[69, 1] - v[29, 1]) / (40 * DT)   # along the incline, over 0.15 … 0.35 s (before it leaves a support)
    expected = -G * (math.sin(THETA) - mu * math.cos(THETA))
    assert accel == pytest.approx(expected, rel=0.03)
    assert abs(v[69, 2]) < 0.05 * abs(v[69, 1])  # it slides along the supports, not off or into them


def test_plank_sticks_when_friction_exceeds_the_slope():
    v = _plank_velocity(0.5, 120)               # μ = 0.5 > tan 15° = 0.27
    assert np.abs(v[60:, 1]).max() < 0.2 * NU   # creep far below the slip tolerance: stuck
