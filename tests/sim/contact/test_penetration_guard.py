"""Penetration guard of the sub-step retry (docs/physics.md §6.2): a (sub)step that ends
deeper than ``[contact] max_penetration`` (default 4 delta; for a step that starts deeper: its start
penetration + limit/4) inside an obstacle is retried with 2, 4, 8, 16 sub-steps; the guard never fails an env. Scenario: the paper arm (dt 0.05 s, 5 Newton iterations,
accept_unconverged) swinging fast into a capsule, which with the guard disabled ends a step deep inside it."""
from __future__ import annotations

import numpy as np
import pytest

from sim import Simulator, build_model, parse_scene
from sim.scene.obstacles import ContactSpec, dump_contact, parse_contact
from sim.scene.tomlio import SceneError
from tests.helpers.paths import REPO

SCENE_PATH = str(REPO / "assets" / "scenes" / "_test.toml")
DELTA = 5e-3
RADIUS = 0.05
ARM_ROD = dict(nodes=21, length=1.0, radius=RADIUS, density=1000.0, youngs_modulus=1e7, poisson_ratio=0.5,
               start=[0.0, 0.0, 0.0], direction=[0.0, 0.0, 1.0], clamp="first_edge")
CAPSULE = dict(type="capsule", start=[0.3, -0.5, 0.55], end=[0.3, 0.5, 0.55], radius=0.05)
OMEGA = 10.0  # initial angular velocity of the arm about its base [rad/s] (tip speed 10 m/s)
STEPS = 6


def swing_into_capsule(mode: str, contact: dict, divergence_guard: float = 0.0) -> list:
    """Arm (upright, clamped) with initial velocity v_x = OMEGA z toward the capsule; per-step StepStats.

    The divergence guard (which also retries the diverging contact step of this swing) is off unless asked
    for, and so is the line search (which keeps this swing's iterates out of the capsule), so these tests see
    the penetration guard alone."""
    doc = {"sim": dict(dt=0.05, gravity=[0.0, 0.0, 0.0], damping=0.0, newton_tol=1e-3, newton_max_iter=5,
                       accept_unconverged=True, mode=mode, divergence_guard=divergence_guard, line_search="none"),
           "rod": dict(ARM_ROD), "obstacle": [dict(CAPSULE)], "contact": dict(contact)}
    sim = Simulator(build_model(parse_scene(doc, SCENE_PATH)), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    st.dof_vel[0, 2:, 0] = OMEGA * st.node_pos[0, 2:, 2]
    hist = []
    for _ in range(STEPS):
        s = sim.step(st, ctrl)
        assert np.isfinite(st.dof).all() and np.isfinite(st.dof_vel).all()
        hist.append(s)
    return hist


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_guard_limits_penetration_of_a_fast_swing(mode):
    off = swing_into_capsule(mode, {"max_penetration": 1e9, "step_limit": False})
    on = swing_into_capsule(mode, {"step_limit": False})   # the guard alone (the step limit is tested apart)
    pen_off = max(float(s.max_penetration[0]) for s in off)
    pen_on = max(float(s.max_penetration[0]) for s in on)
    limit = 4 * DELTA
    # the scenario reproduces the problem: unguarded, one step ends deeper than the arm radius
    assert pen_off > RADIUS, f"unguarded swing only reached {1e3 * pen_off:.1f} mm"
    assert all(int(s.substeps[0]) == 1 for s in off)
    # guarded: retries happened, the penetration stays within the limit, nothing failed
    assert max(int(s.substeps[0]) for s in on) > 1
    assert pen_on <= limit, f"guarded swing penetrated {1e3 * pen_on:.1f} mm > {1e3 * limit:.1f} mm"
    assert not any(bool(s.failed[0]) for s in on)
    assert all(np.isfinite(s.max_penetration).all() for s in on)


def test_guard_never_fails_an_env():
    """A limit that no sub-step count can meet: every level is too deep, the 16-sub-step result is accepted."""
    hist = swing_into_capsule("2d", {"max_penetration": 1e-9, "step_limit": False})
    assert not any(bool(s.failed[0]) for s in hist)
    assert max(int(s.substeps[0]) for s in hist) == 16
    assert max(float(s.max_penetration[0]) for s in hist) > 1e-9  # the limit was indeed not met


def test_guard_skips_steps_that_start_deep():
    """A step starting deeper than the limit is retried only if it ends deeper than start + limit/4: the
    clamped first edge held 30 mm inside a capsule must not cost 16 sub-steps every step."""
    doc = {"sim": dict(dt=0.05, gravity=[0.0, 0.0, -9.8], damping=0.0, newton_tol=1e-3, newton_max_iter=5,
                       accept_unconverged=True, mode="2d"),
           "rod": dict(ARM_ROD),
           "obstacle": [dict(type="capsule", start=[0.07, -0.5, 0.03], end=[0.07, 0.5, 0.03], radius=0.05)]}
    sim = Simulator(build_model(parse_scene(doc, SCENE_PATH)), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    hist = [sim.step(st, ctrl) for _ in range(10)]
    assert min(float(s.max_penetration[0]) for s in hist) > 4 * DELTA  # stuck deeper than the limit
    assert all(int(s.substeps[0]) == 1 and not bool(s.failed[0]) for s in hist)
    assert np.isfinite(st.dof).all()


def test_contact_max_penetration_key():
    c = parse_contact({"max_penetration": 0.01}, "s.toml")
    assert c.max_penetration == 0.01
    assert parse_contact({}, "s.toml").max_penetration is None
    for bad, msg in ((0.0, "> 0"), (-1.0, "> 0"), (float("inf"), "finite"), ("x", "number")):
        with pytest.raises(SceneError, match=f"contact.max_penetration.*{msg}"):
            parse_contact({"max_penetration": bad}, "s.toml")
    # dump -> parse round trip, with and without the key
    import tomllib
    for spec in (ContactSpec(max_penetration=0.03), ContactSpec(delta=2e-3)):
        back = parse_contact(tomllib.loads("\n".join(dump_contact(spec)))["contact"], "s.toml")
        assert back == spec
