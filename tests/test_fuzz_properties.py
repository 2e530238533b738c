"""Hardening, property-based fuzz (hypothesis; bounded, derandomised): over scene documents, control arrays,
env overrides/actions and CLI arguments, every input is either refused with a SceneError/ValueError (or CLI exit
status 2) naming the key / field, or runs with no NaN in the state, observations or statistics and keeps every
accepted value as given. The case functions are benchmarks/fuzz.py's (`rodlab bench fuzz` for long runs)."""
from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.fuzz import (
    BASE,
    KEYS,
    NASTY,
    random_cli_case,
    random_control_case,
    random_env_case,
    run_cli_case,
    run_control_case,
    run_env_case,
    run_scene_case,
)

GOOD = ("ok", "clear_error")
_S = settings(max_examples=150, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

values = st.one_of(
    st.sampled_from(NASTY),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=1e-12, max_value=1e12),
    st.integers(min_value=-(2 ** 63), max_value=2 ** 63 - 1),
    st.integers(min_value=-5, max_value=60),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
    st.lists(st.floats(min_value=-1e3, max_value=1e3), min_size=3, max_size=4),
    st.text(max_size=4),
    st.booleans(),
)


@_S
@given(edits=st.lists(st.tuples(st.integers(0, len(KEYS) - 1), values), min_size=1, max_size=3))
def test_scene_documents_are_refused_naming_the_key_or_run_without_nan(edits):
    import copy

    doc = copy.deepcopy(BASE)
    for k, v in edits:
        table, idx, key = KEYS[k]
        (doc[table][idx] if idx is not None else doc[table])[key] = v
    outcome, detail = run_scene_case(doc, steps=2)
    assert outcome in GOOD, (edits, detail)


@settings(max_examples=80, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_control_arrays_and_state_corruption(seed):
    case = random_control_case(np.random.default_rng(seed))
    outcome, detail = run_control_case(case, steps=2)
    assert outcome in GOOD, (case, detail)


@settings(max_examples=20, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_env_overrides_and_actions(seed):
    case = random_env_case(np.random.default_rng(seed))
    outcome, detail = run_env_case(case)
    assert outcome in GOOD, (case, detail)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_cli_arguments(seed, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fuzzcli")
    (tmp / "f.txt").write_text("not a folder")
    args = random_cli_case(np.random.default_rng(seed), str(tmp))
    outcome, detail = run_cli_case(args)
    assert outcome in GOOD, (args, detail)


def test_the_fuzz_detects_what_it_should():
    """The classifier itself: a clean scene runs ok, a refused key is a clear error, and a value read
    differently from what was given would be silent-wrong."""
    import copy

    from benchmarks.fuzz import _kept_as_given
    from sim.scene.spec import parse_scene

    assert run_scene_case(copy.deepcopy(BASE))[0] == "ok"
    doc = copy.deepcopy(BASE)
    doc["rod"]["radius"] = 1e-300
    out, msg = run_scene_case(doc)
    assert out == "clear_error" and "rod.radius" in msg
    spec = parse_scene(copy.deepcopy(BASE), "fuzz.toml")
    doc = copy.deepcopy(BASE)
    doc["sim"]["newton_max_iter"] = 2.5
    assert "newton_max_iter" in _kept_as_given(spec, doc)
    assert math.isfinite(spec.sim.dt)
