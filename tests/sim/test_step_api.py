"""Simulator API: control validation, control helpers, reset_envs, material frames, State properties; NaN state
never stays in the state or StepStats, dtypes/None give errors naming the field, reset_envs takes integer indices
(sim/scene/validate.py; docs/conventions.md "Input bounds")."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from sim import Simulator, build_model, load_scene
from tests.helpers.paths import SCENES


@pytest.fixture(scope="module")
def sim():
    return Simulator(build_model(load_scene(SCENES / "arm.toml")), envs=3)


@pytest.fixture
def arm(sim):
    return sim, sim.reset(), sim.make_control()


def test_bad_controls_raise_naming_the_field(arm):
    sim, state, ctrl = arm
    ctrl.kappa_bar[1, 5, 0] = np.nan
    with pytest.raises(ValueError, match="ctrl.kappa_bar"):
        sim.step(state, ctrl)
    ctrl.kappa_bar[1, 5, 0] = 0.0
    ctrl.tau_bar[0, 3] = np.inf
    with pytest.raises(ValueError, match="ctrl.tau_bar"):
        sim.step(state, ctrl)
    ctrl.tau_bar = np.zeros((3, 20))
    with pytest.raises(ValueError, match="ctrl.tau_bar.*shape"):
        sim.step(state, ctrl)
    state.dof = state.dof[:, :, :3].copy()
    with pytest.raises(ValueError, match="state.dof"):
        sim.step(state, sim.make_control())


def test_control_helpers_and_increments_act_in_the_current_step(arm):
    sim, state, ctrl = arm
    sim.set_natural_curvature(ctrl, [0.05, 0.0], nodes=slice(1, -1), envs=[1])
    sim.add_natural_curvature(ctrl, [0.0, 0.02], nodes=slice(1, -1), envs=2)
    sim.add_natural_twist(ctrl, 0.01, nodes=slice(1, -1), envs=2)
    assert np.all(ctrl.kappa_bar[1, 1:-1, 0] == 0.05) and np.all(ctrl.kappa_bar[0] == 0)
    st = sim.step(state, ctrl)
    tip = state.node_pos[:, -1]
    assert tip[1, 0] < -1e-3 and abs(tip[0, 0]) < 1e-12       # env 1 bent toward −x in this very step
    assert tip[2, 1] < -1e-4                                    # κ̄2 > 0 bends the upright arm toward −y
    assert st.energy_bend[1] > 0 and st.energy_twist[2] > 0 and np.all(st.substeps == 1)


def test_reset_envs_and_material_frames(arm):
    sim, state, ctrl = arm
    ctrl.kappa_bar[:, 1:-1, :] = 0.05
    ctrl.tau_bar[:, 1:-1] = 0.02
    for _ in range(5):
        sim.step(state, ctrl)
    m1, m2, t = sim.material_frames(state)
    for a, b in ((m1, m2), (m1, t), (m2, t)):
        assert np.abs((a * b).sum(-1)).max() < 1e-12
    assert np.abs(np.linalg.norm(m1, axis=-1) - 1).max() < 1e-12
    assert np.allclose(np.cross(m1, m2), t, atol=1e-12)
    before = state.copy()
    sim.reset_envs(state, ctrl, np.array([False, True, False]))
    fresh = sim.reset()
    assert np.array_equal(state.dof[1], fresh.dof[1]) and state.time[1] == 0 and np.all(ctrl.kappa_bar[1] == 0)
    assert np.array_equal(state.dof[[0, 2]], before.dof[[0, 2]]) and np.all(ctrl.kappa_bar[0, 1:-1] == 0.05)
    assert state.node_pos.shape == (3, 21, 3) and state.edge_theta.shape == (3, 20)


def test_2d_state_properties(scenes_dir):
    sim = Simulator(build_model(load_scene(scenes_dir / "arm_2d.toml")), envs=2)
    state = sim.reset()
    assert state.dof.shape == (2, 21, 2) and state.node_pos.shape == (2, 21, 3)
    assert np.allclose(state.node_pos[0, :, 2], np.linspace(0, 1, 21))
    assert np.all(state.edge_theta == 0) and state.edge_theta.shape == (2, 20)



def _all_finite(stats) -> bool:
    return all(np.isfinite(a).all() for a in vars(stats).values() if isinstance(a, np.ndarray))


@pytest.mark.parametrize("field, index", [("dof", (1, 7, 0)), ("dof_vel", (1, 3, 2)), ("edge_ref_d1", (1, 4, 1)),
                                          ("edge_tangent", (1, 9, 2)), ("node_ref_twist", (1, 5))])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_nonfinite_state_marks_env_failed_and_leaves_no_nan(sim, field, index, bad):
    state, ctrl = sim.reset(), sim.make_control()
    sim.step(state, ctrl)
    getattr(state, field)[index] = bad
    stats = sim.step(state, ctrl)
    assert state.failed.tolist() == [False, True, False]
    assert stats.failed[1] and not stats.converged[1]
    for name in ("dof", "dof_vel", "edge_ref_d1", "edge_tangent", "node_ref_twist", "time"):
        assert np.isfinite(getattr(state, name)).all(), name
    assert _all_finite(stats)
    # the failed env holds the rest configuration (documented), the others moved on normally
    np.testing.assert_array_equal(state.dof[1], sim.reset().dof[1])
    # it stays frozen and finite, and reset_envs brings it back
    sim.step(state, ctrl)
    assert state.failed[1] and np.isfinite(state.dof).all()
    sim.reset_envs(state, ctrl, [1])
    assert not state.failed.any()


def test_complex_kappa_bar_is_refused_without_a_cast(sim):
    state, ctrl = sim.reset(), sim.make_control()
    ctrl.kappa_bar = ctrl.kappa_bar.astype(np.complex128) + 1e-3j
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning either: an error before any cast
        with pytest.raises(ValueError, match=r"ctrl\.kappa_bar: expected dtype float64, got complex"):
            sim.step(state, ctrl)


@pytest.mark.parametrize("owner, field, dtype", [("state", "dof", object), ("state", "dof_vel", "U8"),
                                                 ("ctrl", "kappa_bar", object), ("ctrl", "tau_bar", "U8"),
                                                 ("state", "failed", np.float64)])
def test_object_and_str_dtypes_name_the_field(sim, owner, field, dtype):
    state, ctrl = sim.reset(), sim.make_control()
    obj = state if owner == "state" else ctrl
    setattr(obj, field, getattr(obj, field).astype(dtype))
    with pytest.raises(ValueError, match=rf"{owner}\.{field}: expected dtype"):
        sim.step(state, ctrl)


def test_step_with_none_names_the_argument(sim):
    state, ctrl = sim.reset(), sim.make_control()
    with pytest.raises(ValueError, match="step: ctrl: expected a sim.Control"):
        sim.step(state, None)
    with pytest.raises(ValueError, match="step: state: expected a sim.State"):
        sim.step(None, ctrl)


def test_float32_controls_are_still_accepted(sim):
    state, ctrl = sim.reset(), sim.make_control()
    ctrl.kappa_bar = ctrl.kappa_bar.astype(np.float32)
    assert not sim.step(state, ctrl).failed.any()


def test_reset_envs_integer_list_means_indices_and_bool_arrays_stay_masks(sim):
    state, ctrl = sim.reset(), sim.make_control()
    for sel, want in (([0, 1], [True, True, False]), ([2], [False, False, True]), ((1,), [False, True, False]),
                      (np.array([0]), [True, False, False]), (2, [False, False, True]), ([-1], [False, False, True]),
                      ([True, False, True], [True, False, True]), (np.array([False, True, False]), [False, True, False]),
                      ([], [False, False, False])):
        state.failed[:] = True
        sim.reset_envs(state, ctrl, sel)
        assert (~state.failed).tolist() == want, sel
    # the old reading of [0, 1] as a mask would reset env 1 only; now it is env 0 and env 1 (above)
    for bad in ([0, True], [0.0, 1.0], [3], [-4], np.zeros((3, 1), bool), np.array([True, False]), True, "0"):
        with pytest.raises(ValueError, match="reset_envs"):
            sim.reset_envs(state, ctrl, bad)


def test_huge_finite_frames_in_2d_leave_no_nan_after_the_step():
    """Found by the fuzz: edge_tangent = 1e300 (finite, so not caught before the step) in a 2-D env gave a NaN
    reference twist after the step; every state field is checked after the step too."""
    from benchmarks.fuzz import run_control_case

    case = {"mode": "2d", "kind": "state_huge", "field": "kappa_bar", "state_field": "edge_tangent",
            "scale": 0.0035, "seed": 608752367}
    assert run_control_case(case) == ("ok", "")
