"""Regression: the arm trajectories match tests/regression/golden/arm_trajectories.npz.

Tolerance 1e-9 m (relative 1e-9): bit-level differences between CPUs (FMA contraction) are allowed, physics
changes are not. Regenerate with `python -m tests.regression.golden_arm` after an intended change."""
from __future__ import annotations

import numpy as np

from tests.regression.golden_arm import GOLDEN, run


def test_arm_trajectories_match_golden():
    ref = np.load(GOLDEN)
    for scene in ("arm.toml", "arm_2d.toml"):
        got = run(scene)
        key = scene.split(".")[0]
        for name in ("dof", "dof_vel", "tip"):
            np.testing.assert_allclose(got[name], ref[f"{key}/{name}"], rtol=1e-9, atol=1e-9, err_msg=f"{key}/{name}")
        assert np.array_equal(got["newton_iters"], ref[f"{key}/newton_iters"]), key
