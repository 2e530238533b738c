"""Synthetic measurements for the fit tests (sim.analysis.calibration and the workbench's Fit tab): made by rodlab at known
unknowns plus NOISE_M Gaussian noise, and written as the measurement CSV `rodlab fit` reads."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.analysis import calibration as F

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
