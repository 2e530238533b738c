"""Hardening, make_vec_env: wrong override types and missing scene files give clear errors; the paper's arm
comes from the shipped scene file only (no scene built in code)."""
from __future__ import annotations

import numpy as np
import pytest

from policies import make_vec_env
from sim.scene import SceneError


@pytest.mark.parametrize("kw, match", [
    ({"dt": "0.05"}, r"dt: expected a finite number, got str '0.05'"),
    ({"dt": float("nan")}, r"dt: expected a finite number"),
    ({"newton_max_iter": 2.5}, r"newton_max_iter: expected an integer, got float 2.5"),
    ({"substeps": True}, r"substeps: expected an integer"),
    ({"smoothing": 3}, r"smoothing: expected a string"),
    ({"scene": 1}, r"scene: expected a string"),
    ({"no_such_field": 1}, r"has no field 'no_such_field'"),
    ({"substeps": 2 ** 62}, r"substeps: must be within \[1, 1000\]"),   # found by the fuzz: a hang
])
def test_bad_overrides_name_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        make_vec_env("follow_target", 2, **kw)


@pytest.mark.parametrize("num_envs, seed", [("2", None), (0, None), (2.0, None), (2, "1"), (2, 1.5)])
def test_bad_num_envs_or_seed(num_envs, seed):
    with pytest.raises(ValueError, match="num_envs|seed"):
        make_vec_env("follow_target", num_envs, seed=seed)


def test_missing_scene_file_is_an_error_not_a_fallback(tmp_path):
    missing = str(tmp_path / "nonexistent.toml")
    with pytest.raises(SceneError, match=r"nonexistent\.toml: file not found"):
        make_vec_env("follow_target", 1, scene=missing)


def test_the_arm_comes_from_the_shipped_file_and_scene_none_means_it():
    import policies.tasks.scenes as scenes

    assert not hasattr(scenes, "_arm_scene_in_code")
    a = make_vec_env("follow_target", 1, seed=0)
    b = make_vec_env("follow_target", 1, seed=0, scene=None)
    assert a.core.model.spec.path.endswith("assets/scenes/arm.toml")
    assert b.core.model.spec.path == a.core.model.spec.path
    np.testing.assert_array_equal(a.core.model.rest_node_pos, b.core.model.rest_node_pos)


def test_integer_dt_override_still_works():
    env = make_vec_env("follow_target", 1, seed=0, dt=1, substeps=np.int64(2))
    obs, _ = env.reset(seed=0)
    assert env.core.model.dt == 1.0 and np.isfinite(obs).all()


def test_reset_mask_takes_integer_indices_too():
    env = make_vec_env("follow_target", 3, seed=0)
    env.reset(seed=0)
    for _ in range(2):
        env.step(np.zeros((3, env.single_action_space.shape[0]), np.float32))
    env.reset(options={"reset_mask": [1]})  # env 1 only
    env.reset(options={"reset_mask": [2]})  # read as a mask, [2] would have reset env 0
    assert env.core.step_count.tolist() == [2, 0, 0]
    env.reset(options={"reset_mask": np.array([True, False, False])})
    assert env.core.step_count.tolist() == [0, 0, 0]
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"reset_mask": [0, True]})


@pytest.mark.parametrize("kw, match", [
    ({"dt": "0.05"}, r"FollowTargetConfig\.dt: expected a finite number"),
    ({"substeps": 2.5}, r"\.substeps: expected an integer"),
    ({"newton_max_iter": 0}, r"\.newton_max_iter: must be within"),
    ({"timeout_steps": True}, r"\.timeout_steps: expected an integer"),
    ({"smoothing": 3}, r"\.smoothing: expected a string"),
])
def test_task_config_built_directly_checks_its_fields(kw, match):
    from policies.tasks.follow_target import FollowTargetConfig

    with pytest.raises(ValueError, match=match):
        FollowTargetConfig(**kw)
