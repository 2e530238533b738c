"""Hardening, Python API: NaN state never stays in the state or StepStats, dtypes/None give errors naming the
field, reset_envs takes integer indices (sim/validate.py; docs/conventions.md "Input bounds")."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from sim import Simulator, build_model, load_scene


@pytest.fixture(scope="module")
def sim():
    return Simulator(build_model(load_scene("assets/scenes/arm.toml")), envs=3)


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
