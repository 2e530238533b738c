"""Synthetic measurements for the fit tests (sim.analysis.calibration and the workbench's Fit tab): made by rodlab at known
unknowns plus NOISE_M Gaussian noise, and written as the measurement CSV `rodlab fit` reads."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from sim.analysis import calibration as F
from sim.scene.model import build_model
from sim.scene.spec import dump_scene, load_scene
from tests.helpers.rodspec import make_spec

NOISE_M = 1e-3


def synthetic(spec, params, z_true, *, seconds=1.5, hz=30.0, markers=5, seed=0, cmds=None):
    """Measurements made by rodlab at the unknowns z_true, with NOISE_M Gaussian noise on each coordinate."""
    t = np.arange(0.0, seconds + 1e-9, 1.0 / hz)
    s = np.linspace(0.25, 1.0, markers)
    meas = F.Measurements(np.repeat(t, markers), np.tile(s, t.size), np.zeros(t.size * markers, int),
                          np.zeros((t.size * markers, 3)))
    prob = F.Problem(spec, meas, cmds, params)
    pos = prob.predict(prob._node_pos(prob.rollout(np.asarray(z_true, float)).dof[:, 0],
                                      prob.model0.plane_y if prob.planar else None))
    noise = np.random.default_rng(seed).normal(0.0, NOISE_M, pos.shape)
    if prob.planar:
        noise[:, 1] = 0.0
    return F.Measurements(meas.t, meas.s, meas.rod, pos + noise), prob


def write_csv(path: Path, meas: F.Measurements) -> Path:
    rows = ["t,s,x,y,z"] + [f"{meas.t[i]:.9g},{meas.s[i]:.9g},{meas.pos[i, 0]:.9g},{meas.pos[i, 1]:.9g},"
                            f"{meas.pos[i, 2]:.9g}" for i in range(meas.t.size)]
    path.write_text("\n".join(rows) + "\n")
    return path


def rod_on_a_sphere(center, mode, delta=1e-3):
    """A cantilever sagging onto a sphere under its free end."""
    from sim.scene.obstacles import ContactSpec, SphereSpec
    spec = make_spec(nodes=9, length=0.5, radius=0.01, E=1e8, dt=0.01, gravity=(0.0, 0.0, -9.8), damping=2.0,
                     max_iter=60, tol=1e-10, dtol=1e-10, mode=mode)
    return dataclasses.replace(spec, obstacles=(SphereSpec(center=center, radius=0.1, name="ball"),),
                               contact=ContactSpec(stiffness=1e4, delta=delta))


def commanded_scene(tmp_path: Path, mode: str):
    """A 9-node clamped rod leaning over under gravity, damped, with curvature commanded at nodes 3 and 6 (loaded
    back from its file): (scene, commands)."""
    p = tmp_path / f"commanded_{mode}.toml"
    direction = tuple(np.array([1.0, 0.0, 0.3]) / np.hypot(1.0, 0.3))
    dump_scene(make_spec(nodes=9, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=0.2, max_iter=30, mode=mode,
                         direction=direction), p)
    spec = load_scene(p)
    path = tmp_path / "controls.csv"
    path.write_text("t,node,kappa1,kappa2,twist\n0,3,0.2,-0.1,0.05\n0.2,3,-0.15,0,0\n0,6,0.3,0.1,0\n")
    return spec, F.load_controls(path, build_model(spec))
