"""Teleoperate the paper's arm headless with natural-curvature commands.

Purpose: the smallest use of the simulator API (docs/physics.md §5): load a scene, build the model, then drive
the arm by setting natural curvature at the control points (nodes 2, 6, 10, 14, 18) while it steps, and print
where the tip goes.

Run:  .venv/bin/python examples/teleop_headless.py            (6 s of simulated time, 500 envs)
      .venv/bin/python examples/teleop_headless.py --smoke    (a few steps, a few envs)
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from sim import Simulator, build_model, load_scene

ROOT = Path(__file__).resolve().parents[1]
CONTROL_POINTS = [2, 6, 10, 14, 18]


def run(envs: int, steps: int) -> np.ndarray:
    """Step ``envs`` arms for ``steps`` steps under a slowly rotating bend; returns the tip positions (envs, 3)."""
    sim = Simulator(build_model(load_scene(ROOT / "assets/scenes/arm.toml")), envs=envs)
    state, ctrl = sim.reset(), sim.make_control()
    phase = np.linspace(0.0, 2 * math.pi, envs, endpoint=False)       # every env bends in its own direction
    for k in range(steps):
        amp = 0.05 * min(1.0, k / 20)                                  # ramp the bend in over 1 s
        kappa = np.stack([amp * np.cos(phase), amp * np.sin(phase)], axis=-1)        # (envs, 2)
        sim.set_natural_curvature(ctrl, np.repeat(kappa[:, None, :], len(CONTROL_POINTS), axis=1),
                                  nodes=CONTROL_POINTS)
        stats = sim.step(state, ctrl)
        if not np.isfinite(state.node_pos).all() or stats.failed.any():
            raise RuntimeError(f"step {k}: simulation failed")
    return state.node_pos[:, -1].copy()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--envs", type=int, default=500)
    ap.add_argument("--steps", type=int, default=120, help="sim steps of 0.05 s")
    ap.add_argument("--smoke", action="store_true", help="a few steps and envs (used by the tests)")
    a = ap.parse_args(argv)
    envs, steps = (4, 5) if a.smoke else (a.envs, a.steps)
    tips = run(envs, steps)
    print(f"{envs} arms after {steps} steps: tip height {tips[:, 2].min():.3f} .. {tips[:, 2].max():.3f} m, "
          f"horizontal reach {np.hypot(tips[:, 0], tips[:, 1]).max():.3f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
