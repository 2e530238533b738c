"""The inverse-statics baseline (policies.model_based) acts through the task's own converter: on the 4D IK task it
brings the tip onto the (static) target and turns its frame onto the target's within a few dozen control steps, on Follow Target it stays far closer to
the moving target than random actions; a task with obstacles is refused by name."""
from __future__ import annotations

import numpy as np
import pytest

from policies.learning.evaluation import evaluate, task_metrics


def tip_errors(policy: str, task: str, steps: int, metric: str = "tip_error") -> list[float]:
    errs: list[float] = []

    def cb(st):
        errs.append(float(np.mean(task_metrics(task, np.asarray(st.next_obs))[metric])))
        return st.t + 1 >= steps

    evaluate(policy, task, episodes=2, num_envs=2, seed=3, callback=cb)
    return errs


def test_inverse_statics_reaches_the_ik_target():
    errs = tip_errors("inverse-statics", "ik4d", 30)
    assert errs[0] > 0.1 and errs[-1] < 0.01, errs


def test_inverse_statics_turns_the_tip_frame_onto_the_ik_target():
    """4D IK asks for a tip frame too (every episode starts at least 90° from it): the baseline commands the twist
    with the curvature and ends within a few degrees."""
    errs = tip_errors("inverse-statics", "ik4d", 40, "orientation_error_deg")
    assert errs[0] > 60.0 and errs[-1] < 5.0, errs


def test_inverse_statics_follows_a_moving_target_better_than_random():
    ours = tip_errors("inverse-statics", "follow_target", 40)
    rand = tip_errors("random", "follow_target", 40)
    assert np.mean(ours[10:]) < 0.5 * np.mean(rand[10:]), (ours, rand)


def test_what_the_baseline_cannot_do_is_refused():
    with pytest.raises(ValueError, match="scenes with contact are not supported"):
        evaluate("inverse-statics", "tight_obstacles_2d", episodes=1, num_envs=1)
