"""Regression: the arm trajectories match tests/sim/regression/golden/arm_trajectories.npz.

Tolerance 1e-9 m (relative 1e-9): bit-level differences between CPUs (FMA contraction) are allowed, physics
changes are not. Regenerate with `python -m tests.helpers.golden_arm` after an intended change."""
from __future__ import annotations

import numpy as np

from tests.helpers.golden_arm import GOLDEN, run


def test_arm_trajectories_match_golden():
    ref = np.load(GOLDEN)
    for scene in ("arm.toml", "arm_2d.toml"):
        got = run(scene)
        key = scene.split(".")[0]
        for name in ("dof", "dof_vel", "tip"):
            np.testing.assert_allclose(got[name], ref[f"{key}/{name}"], rtol=1e-9, atol=1e-9, err_msg=f"{key}/{name}")
        assert np.array_equal(got["newton_iters"], ref[f"{key}/newton_iters"]), key


def test_contact_trajectories_match_golden():
    """Obstacle contact of every kind with friction (3-D and planar) against
    tests/sim/regression/golden/contact_trajectories.npz (tests/helpers/golden_contact.py). Sliding and sticking
    friction amplify rounding: a relative perturbation of 1e-15 of the start moves these trajectories by up to 1e-5 m/s
    in 40 steps (and a kernel build's FMA contraction is such a perturbation), so positions are compared to 0.1 mm,
    velocities to 1 mm/s and contact energies to 0.1 % of their largest; a change of the physics moves them by far
    more."""
    from tests.helpers.golden_contact import CASES
    from tests.helpers.golden_contact import GOLDEN as CONTACT_GOLDEN
    from tests.helpers.golden_contact import run as run_contact

    ref = np.load(CONTACT_GOLDEN)
    for case in CASES:
        got = run_contact(case)
        assert ref[f"{case}/contact_count"].max() > 0, case  # the case does touch
        np.testing.assert_allclose(got["dof"], ref[f"{case}/dof"], rtol=0, atol=1e-4, err_msg=case)
        np.testing.assert_allclose(got["dof_vel"], ref[f"{case}/dof_vel"], rtol=0, atol=1e-3, err_msg=case)
        e_ref = ref[f"{case}/energy_contact"]
        np.testing.assert_allclose(got["energy_contact"], e_ref, rtol=0, atol=1e-3 * e_ref.max(), err_msg=case)
        np.testing.assert_allclose(got["max_penetration"], ref[f"{case}/max_penetration"], rtol=0, atol=1e-6,
                                   err_msg=case)
        assert np.array_equal(got["contact_count"], ref[f"{case}/contact_count"]), case
        assert abs(int(got["newton_iters"].sum()) - int(ref[f"{case}/newton_iters"].sum())) <= \
            0.01 * ref[f"{case}/newton_iters"].sum(), case
