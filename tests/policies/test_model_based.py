"""The inverse-statics baseline (policies.model_based) acts through the task's own converter: on the 4D IK task it
brings the tip onto the (static) target within a few dozen control steps, on Follow Target it stays far closer to
the moving target than random actions; a task with obstacles is refused by name."""
from __future__ import annotations

import numpy as np
import pytest

from policies.learning.evaluation import evaluate, task_metrics


def tip_errors(policy: str, task: str, steps: int) -> list[float]:
    errs: list[float] = []

    def cb(st):
        errs.append(float(np.mean(task_metrics(task, np.asarray(st.next_obs))["tip_error"])))
        return st.t + 1 >= steps

    evaluate(policy, task, episodes=2, num_envs=2, seed=3, callback=cb)
    return errs


def test_inverse_statics_reaches_the_ik_target():
    errs = tip_errors("inverse-statics", "ik4d", 30)
    assert errs[0] > 0.1 and errs[-1] < 0.01, errs


def test_inverse_statics_follows_a_moving_target_better_than_random():
    ours = tip_errors("inverse-statics", "follow_target", 40)
    rand = tip_errors("random", "follow_target", 40)
    assert np.mean(ours[10:]) < 0.5 * np.mean(rand[10:]), (ours, rand)


def test_what_the_baseline_cannot_do_is_refused():
    with pytest.raises(ValueError, match="scenes with contact are not supported"):
        evaluate("inverse-statics", "tight_obstacles_2d", episodes=1, num_envs=1)
