"""A State is the whole per-env state (obstacle poses included, as plain arrays) and the Simulator keeps none: copies
are full snapshots, two states stepped in turn by one Simulator evolve exactly as each alone, resets restore poses,
assign copies one state into another."""
from __future__ import annotations

import numpy as np

from sim import Simulator, build_model, load_scene

FIELDS = ("dof", "dof_vel", "edge_ref_d1", "edge_tangent", "node_ref_twist", "time", "failed", "obstacle_position",
          "obstacle_orientation", "obstacle_a", "obstacle_b", "obstacle_radius", "obstacle_active")


def _tight(scenes_dir, envs=2):
    sim = Simulator(build_model(load_scene(scenes_dir / "tight_obstacles_2d.toml")), envs=envs)
    return sim, sim.reset(), sim.make_control()


def _bend(ctrl, k):
    ctrl.kappa_bar[:, 1:-1, 0] = -0.03 * k  # bends toward the obstacles (+x)


def _same(a, b):
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in FIELDS)


def test_copy_is_a_full_snapshot_with_obstacle_poses(scenes_dir):
    sim, state, ctrl = _tight(scenes_dir)
    ends = sim.contact_data(state).p0[:, 0].copy()
    snap = state.copy()
    sim.set_obstacle_pose(state, 0, (0.0, 0.0, -0.05))  # the original moves; the snapshot keeps its pose
    assert np.array_equal(sim.contact_data(snap).p0[:, 0], ends)
    assert not np.array_equal(sim.contact_data(state).p0[:, 0], ends)
    snap2 = state.copy()
    for k in range(1, 8):  # the copy steps exactly as the original (same poses, same bits)
        _bend(ctrl, k)
        sa, sb = sim.step(state, ctrl), sim.step(snap2, ctrl)
        assert _same(state, snap2) and np.array_equal(sa.contact_count, sb.contact_count)
    assert not any(np.shares_memory(getattr(state, f), getattr(snap2, f)) for f in FIELDS)  # arrays only, copied


def test_the_simulator_keeps_no_per_env_state(scenes_dir):
    """Two states with different obstacle poses, stepped in turn by one Simulator, give the same bits as each
    stepped alone by its own Simulator."""
    sim, a, ctrl = _tight(scenes_dir)
    b = sim.reset()
    for i in range(sim.model.obstacles.count):
        sim.set_obstacle_pose(b, i, (0.01, 0.0, 0.0))
    ref_sim, ref_a, _ = _tight(scenes_dir)
    ref_sim2, ref_b, _ = _tight(scenes_dir)
    for i in range(ref_sim2.model.obstacles.count):
        ref_sim2.set_obstacle_pose(ref_b, i, (0.01, 0.0, 0.0))
    touched = 0
    for k in range(1, 12):
        _bend(ctrl, k)
        sim.step(a, ctrl)
        sb = sim.step(b, ctrl)
        ref_sim.step(ref_a, ctrl)
        ref_sim2.step(ref_b, ctrl)
        touched += int(sb.contact_count.sum())
    assert _same(a, ref_a) and _same(b, ref_b) and not _same(a, b)
    assert touched > 0  # the poses mattered: the bent rod met the obstacles


def test_reset_envs_restores_the_scene_poses_of_those_envs(scenes_dir):
    sim, state, ctrl = _tight(scenes_dir, envs=3)
    p0 = sim.contact_data(state).p0.copy()
    sim.set_obstacle_pose(state, 2, (0.1, 0.0, 0.0))
    sim.reset_envs(state, ctrl, [0, 2])
    assert np.array_equal(sim.contact_data(state).p0[[0, 2]], p0[[0, 2]])
    assert not np.array_equal(sim.contact_data(state).p0[1], p0[1])


def test_node_pos_is_a_new_array_in_both_modes(scenes_dir):
    for scene in ("arm.toml", "arm_2d.toml"):
        sim = Simulator(build_model(load_scene(scenes_dir / scene)), envs=1)
        state = sim.reset()
        x = state.node_pos
        x[...] = 7.0
        assert not np.any(state.node_pos == 7.0), scene


def test_state_arrays_are_the_state_fields_and_copy_copies_each(scenes_dir):
    from sim.state import STATE_ARRAYS, STATE_FLOAT_ARRAYS

    assert STATE_ARRAYS == FIELDS
    assert STATE_FLOAT_ARRAYS == tuple(f for f in FIELDS if f not in ("failed", "obstacle_active"))
    sim, state, _ = _tight(scenes_dir)
    snap = state.copy()
    for name in STATE_ARRAYS:
        a, b = getattr(state, name), getattr(snap, name)
        assert isinstance(a, np.ndarray) and a.shape[0] == sim.envs and not np.shares_memory(a, b)
        assert np.array_equal(a, b)


def test_assign_copies_every_array_in_place(scenes_dir):
    sim, state, ctrl = _tight(scenes_dir)
    other = sim.reset()
    sim.set_obstacle_pose(other, 1, (0.02, 0.0, 0.0))
    _bend(ctrl, 3)
    sim.step(other, ctrl)
    arrays = {f: getattr(state, f) for f in FIELDS}
    state.assign(other)
    assert all(getattr(state, f) is arrays[f] for f in FIELDS)  # the same arrays, new values
    assert _same(state, other) and np.array_equal(state.obstacle_position, other.obstacle_position)
    small = Simulator(sim.model, envs=1).reset()
    import pytest

    with pytest.raises(ValueError, match="shape"):
        state.assign(small)


def test_a_zero_obstacle_quaternion_is_refused_by_name(scenes_dir):
    sim, state, ctrl = _tight(scenes_dir)
    sim.step(state, ctrl)
    state.obstacle_orientation[1, 0] = 0.0
    import pytest

    with pytest.raises(ValueError, match="state.obstacle_orientation: a quaternion is zero"):
        sim.step(state, ctrl)


def test_a_nan_obstacle_pose_fails_that_env_and_goes_back_to_the_scene(scenes_dir):
    sim, state, ctrl = _tight(scenes_dir, envs=3)
    spec_pose = state.obstacle_position.copy()
    sim.set_obstacle_pose(state, 0, (0.01, 0.0, 0.0), envs=[0, 2])
    state.obstacle_position[2, 0, 1] = np.nan
    stats = sim.step(state, ctrl)
    assert stats.failed.tolist() == [False, False, True] and state.failed[2]
    assert np.array_equal(state.obstacle_position[2], spec_pose[2])  # the NaN pose is the scene's again
    np.testing.assert_allclose(state.obstacle_position[0, 0], (0.01, 0.0, 0.0))  # the others keep theirs
    assert all(np.isfinite(getattr(state, f)).all() for f in FIELDS if f != "failed")
