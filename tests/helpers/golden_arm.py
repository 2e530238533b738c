"""Golden trajectories of the RL arm (3-D and 2-D). Regenerate ONLY after an intended physics change:

    .venv/bin/python -m tests.helpers.golden_arm
"""
from __future__ import annotations

import numpy as np

from sim import Simulator, build_model, load_scene
from tests.helpers.paths import REPO

GOLDEN = REPO / "tests" / "sim" / "regression" / "golden" / "arm_trajectories.npz"
STEPS = 30


def run(scene: str) -> dict[str, np.ndarray]:
    """3 envs, 30 steps of 0.05 s: env 0 rest (gravity sag), env 1 κ̄1 ramp, env 2 κ̄1/κ̄2 + twist ramp."""
    sim = Simulator(build_model(load_scene(REPO / "assets" / "scenes" / scene)), envs=3)
    state = sim.reset()
    ctrl = sim.make_control()
    iters, tips = [], []
    for k in range(STEPS):
        sim.add_natural_curvature(ctrl, [0.006, 0.0], nodes=slice(1, -1), envs=1)
        sim.add_natural_curvature(ctrl, [-0.004, 0.005], nodes=slice(1, -1), envs=2)
        sim.add_natural_twist(ctrl, 0.01, nodes=slice(1, -1), envs=2)
        st = sim.step(state, ctrl)
        iters.append(st.newton_iters.copy())
        tips.append(state.node_pos[:, -1].copy())
    return {"dof": state.dof.copy(), "dof_vel": state.dof_vel.copy(), "newton_iters": np.array(iters),
            "tip": np.array(tips)}


def main() -> None:
    out = {}
    for scene in ("arm.toml", "arm_2d.toml"):
        for k, v in run(scene).items():
            out[f"{scene.split('.')[0]}/{k}"] = v
    GOLDEN.parent.mkdir(exist_ok=True)
    np.savez_compressed(GOLDEN, **out)
    print(f"wrote {GOLDEN}")


if __name__ == "__main__":
    main()
