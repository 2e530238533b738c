"""Derivatives of a rollout (sim.analysis.gradients, docs/physics.md §3.9): tangents against central differences of whole
rollouts for every parameter in 2-D and 3-D, with a step-size study; the adjoint against the tangent mode; what
is not covered is refused by name."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sim.analysis import gradients as G
from sim.geometry.frames import update_frames
from sim.scene.boundary import DragSpec, FixSpec
from sim.scene.model import build_model
from sim.scene.obstacles import BoxSpec, CapsuleSpec, ContactSpec, CylinderSpec, PlaneSpec, SphereSpec
from sim.step import Simulator
from tests.helpers.rodspec import make_spec

T, B = 5, 2
DIRECTION = tuple(np.array([0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0))  # leaning over: gravity bends it


ROD = dict(nodes=8, radius=0.05, dt=0.02, gravity=(0.0, 0.0, -9.8), damping=0.3, tol=1e-13, dtol=1e-13, max_iter=60,
           direction=DIRECTION)  # a bent-over clamped rod under gravity, damped, Newton converged tightly


def simulator(mode: str, **kw) -> Simulator:
    """The :data:`ROD` of 8 nodes; ``kw`` as make_spec."""
    return Simulator(build_model(make_spec(**{**ROD, "mode": mode, **kw})), envs=B)


def controls(sim, kb, tb, force=None):
    out = []
    for k in range(T):
        c = sim.make_control()
        c.kappa_bar += kb[k]
        c.tau_bar += tb[k]
        if force is not None:
            c.force = force[k].copy()
        out.append(c)
    return out


def start(sim, dof0=None, vel0=None):
    st = sim.reset()
    if vel0 is not None:
        st.dof_vel.reshape(B, -1)[:] = vel0
    if dof0 is not None:  # the stored frames follow the DOFs by parallel transport (as a step carries them)
        st.dof.reshape(B, -1)[:] = dof0
        if sim.model.mode == "3d":
            for e in range(B):
                pos = dof0[e].reshape(-1, 4)[:, :3].copy()
                E = pos.shape[0] - 1
                t, d1, d2, le, beta = (np.empty((E, 3)), np.empty((E, 3)), np.empty((E, 3)), np.empty(E),
                                       np.empty(E + 1))
                update_frames(pos, st.edge_ref_d1[e].copy(), st.edge_tangent[e].copy(), st.node_ref_twist[e].copy(),
                              t, d1, d2, le, beta)
                st.edge_tangent[e], st.edge_ref_d1[e], st.node_ref_twist[e] = t, d1, beta
    return st


def random_controls(mode: str, N: int, rng):
    """Natural curvature and twist for every step and env around the rest values (2-D: κ1 only)."""
    kb = rng.normal(0.0, 0.05, (T, B, N, 2))
    tb = rng.normal(0.0, 0.05, (T, B, N)) if mode == "3d" else np.zeros((T, B, N))
    if mode == "2d":
        kb[..., 1] = 0.0
    return kb, tb


def _check_adjoint(tape, checked, rng, *, velocities=False) -> dict:
    """⟨vjp(c), t⟩ = ⟨c, jvp(t)⟩ for a random cotangent on every state (and on the final velocities) and each checked
    tangent t; returns the gradients."""
    n = tape.dof.shape[2]
    cot = {"dof": rng.normal(0.0, 1.0, (T + 1, B, n))}
    if velocities:
        cot["vel"] = rng.normal(0.0, 1.0, (B, n))
    grads = tape.vjp(cot)
    for name, (tangent, _) in checked.items():
        out = tape.jvp(tangent)
        rhs = np.sum(cot["dof"] * out["dof"]) + (np.sum(cot["vel"] * out["vel"][-1]) if velocities else 0.0)
        lhs = sum(np.sum(grads[k] * v) for k, v in tangent.items())
        assert lhs == pytest.approx(rhs, rel=1e-10), name
    return grads


def final_dof(sim, kb, tb, force=None, **kw) -> np.ndarray:
    st = start(sim, **kw)
    for c in controls(sim, kb, tb, force):
        sim.step(st, c)
    return st.dof.reshape(B, -1).copy()


@pytest.fixture(scope="module", params=["2d", "3d"])
def case(request):
    mode = request.param
    rng = np.random.default_rng(0)
    sim = simulator(mode)
    N = sim.model.node_count
    kb = rng.normal(0.0, 0.05, (T, B, N, 2))
    tb = rng.normal(0.0, 0.05, (T, B, N))
    if mode == "2d":
        kb[..., 1] = 0.0
        tb[:] = 0.0
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    return mode, sim, kb, tb, tape, rng


def perturbations(mode, sim, kb, tb, tape, rng, make=simulator):
    """name -> (tangent dict, function eps -> final DOFs of the rollout with the parameters moved by eps·tangent);
    ``make(mode, **kw)`` builds the simulator with changed scene values."""
    n = tape.dof.shape[2]
    free = ~sim.kernel_rod.fixed.astype(bool)
    dk = rng.normal(0.0, 1.0, kb.shape)
    dt_ = rng.normal(0.0, 1.0, tb.shape)
    if mode == "2d":
        dk[..., 1] = 0.0
    g = np.array([0.3, -0.2 if mode == "3d" else 0.0, 0.5])
    # point forces [N] on every node and step (their own stream: the callers' draws after this stay as they were)
    df = np.random.default_rng(11).normal(0.0, 0.5, (T, B, sim.model.node_count, 3))
    v0 = rng.normal(0.0, 0.1, (B, n)) * free
    x0 = rng.normal(0.0, 0.01, (B, n)) * free
    one = np.ones(B)
    out = {
        # the scene ties G to E through ν: a change of E there is a change of both factors
        "log_youngs_modulus": ({"log_youngs_modulus": one, "log_shear_modulus": one}, lambda eps: final_dof(
            make(mode, E=1e6 * math.exp(eps)), kb, tb)),
        "log_density": ({"log_density": one}, lambda eps: final_dof(
            make(mode, density=1000.0 * math.exp(eps)), kb, tb)),
        "log_radius": ({"log_radius": one}, lambda eps: final_dof(
            make(mode, radius=sim.model.spec.rods[0].radius * math.exp(eps)), kb, tb)),
        "damping": ({"damping": one}, lambda eps: final_dof(make(mode, damping=0.3 + eps), kb, tb)),
        "gravity": ({"gravity": np.tile(g, (B, 1))}, lambda eps: final_dof(
            make(mode, gravity=tuple(np.array([0.0, 0.0, -9.8]) + eps * g)), kb, tb)),
        "kappa_bar": ({"kappa_bar": dk}, lambda eps: final_dof(sim, kb + eps * dk, tb)),
        "force": ({"force": df}, lambda eps: final_dof(sim, kb, tb, eps * df)),
        "vel0": ({"vel0": v0}, lambda eps: final_dof(sim, kb, tb, vel0=tape.vel[0] + eps * v0)),
        "dof0": ({"dof0": x0}, lambda eps: final_dof(sim, kb, tb, dof0=tape.dof[0] + eps * x0)),
    }
    if mode == "3d":
        out["tau_bar"] = ({"tau_bar": dt_}, lambda eps: final_dof(sim, kb, tb + eps * dt_))
    return out


def _check_tangents(tape, perturbed, steps=(1e-4, 1e-5, 1e-6), smallest=1e-4):
    for name, (tangent, moved) in perturbed.items():
        jvp = tape.jvp(tangent)["dof"][-1]
        assert np.linalg.norm(jvp) > smallest, name  # the final state depends on every parameter here
        errors = {}
        for eps in steps:  # step-size study: truncation error at large steps, rounding at small
            fd = (moved(eps) - moved(-eps)) / (2.0 * eps)
            errors[eps] = np.linalg.norm(fd - jvp) / np.linalg.norm(fd)
        assert min(errors.values()) <= 1e-6, (name, errors)
        assert np.all(np.isfinite(jvp))


def test_tangents_match_central_differences_of_the_rollout(case):
    mode, sim, kb, tb, tape, rng = case
    assert tape.unconverged == 0
    _check_tangents(tape, perturbations(*case))


GAP = 0.002  # between the rod's surface and the obstacle at the start: within the contact's delta (5 mm)


def _obstacle(kind: str):
    """An obstacle just beside the top of the leaning rod, on the side gravity bends it toward."""
    tip = np.array(DIRECTION)
    if kind == "plane":
        return PlaneSpec(point=tuple(tip + [0.05 + GAP, 0.0, 0.0]), normal=(-1.0, 0.0, 0.0))
    if kind == "sphere":
        return SphereSpec(center=tuple(tip + [0.2 + 0.05 + GAP, 0.0, -0.05]), radius=0.2)
    if kind in ("capsule", "cylinder"):  # across the rod's plane (the cylinder: a triangle mesh prism)
        c = tip + [0.1 + 0.05 + GAP, 0.0, -0.05]
        spec = CapsuleSpec if kind == "capsule" else CylinderSpec
        return spec(start=tuple(c - [0.0, 0.3, 0.0]), end=tuple(c + [0.0, 0.3, 0.0]), radius=0.1)
    return BoxSpec(position=tuple(tip + [0.1 + 0.05 + GAP, 0.0, 0.0]), half_extents=(0.1, 0.3, 0.3))  # a face


def contact_simulator(mode: str, kind: str, mu: float = 0.0, nu: float = 1e-2, k: float = 1e4, delta: float = 5e-3,
                      **kw) -> Simulator:
    """:func:`simulator` with an obstacle of ``kind`` it presses against (contact stiffness ``k``), friction ``mu``
    with velocity tolerance ``nu``, and the default line search (friction's Newton needs it: docs/physics.md §4.6)."""
    spec = make_spec(**{**ROD, "mode": mode, "line_search": "auto", **kw})
    spec = dataclasses.replace(spec, obstacles=(_obstacle(kind),),
                               contact=ContactSpec(stiffness=k, delta=delta, friction=mu,
                                                   friction_velocity_tol=nu))
    return Simulator(build_model(spec), envs=B)


def posed_dof(sim, kb, tb, moved=None, turned=None) -> np.ndarray:
    """:func:`final_dof` with the obstacles moved by ``moved`` (B, M, 3) [m] or turned by the rotation vectors
    ``turned`` (B, M, 3) (world axes, about each obstacle's origin) before the rollout."""
    st = start(sim)
    if moved is not None:
        st.obstacle_position[:] += moved
    if turned is not None:
        for e in range(B):
            for j in range(turned.shape[1]):
                w = turned[e, j]
                a = np.linalg.norm(w)
                q = np.r_[math.cos(0.5 * a), math.sin(0.5 * a) * w / a] if a > 0 else np.r_[1.0, 0.0, 0.0, 0.0]
                st.obstacle_orientation[e, j] = G._quat_mul(q, st.obstacle_orientation[e, j])
    for c in controls(sim, kb, tb):
        sim.step(st, c)
    return st.dof.reshape(B, -1).copy()


FRICTION = {"frictionless": (0.0, 1e-2), "sliding": (0.3, 1e-3), "sticking": (0.5, 1.0)}  # μ, ν [m/s]
CONTACT_CASES = [(mode, kind, regime) for mode in ("2d", "3d")
                 for kind in ("plane", "sphere", "capsule", "cylinder", "box") for regime in FRICTION]


@pytest.mark.parametrize("mode,kind,regime", CONTACT_CASES)
def test_tangents_through_obstacle_contact_match_central_differences(mode, kind, regime):
    """The leaning rod pressed against an obstacle over the last steps, without friction, sliding along it (the
    friction force at μ N: slip beyond the law's velocity tolerance ν) and on the law's sticking branch (below
    μ N): the contact enters every derivative (without it they differ by far more than the tolerance)."""
    mu, nu = FRICTION[regime]
    rng = np.random.default_rng(1)
    sim = contact_simulator(mode, kind, mu, nu)
    N = sim.model.node_count
    kb, tb = random_controls(mode, N, rng)
    st = start(sim)
    touched = []
    ctrls = controls(sim, kb, tb)
    tape = G.rollout(sim, st, ctrls)
    assert tape.unconverged == 0 and tape.contact is not None
    st2 = start(sim)
    ratio = []  # |friction| / μ N of each env in touch, each step: 1 sliding, below it sticking
    for c in ctrls:
        last = sim.step(st2, c)
        touched.append(last.contact_count.copy())
        ratio += [np.linalg.norm(last.contact_friction_force[e, :k], axis=-1).sum()
                  / (max(mu, 1e-300) * last.contact_normal_force[e, :k].sum())
                  for e, k in enumerate(last.contact_count) if k > 0]
    assert np.all(np.array(touched)[-2:] > 0), touched  # in contact over the last steps, every env
    if mu > 0.0:  # the friction law's branch: sliding on some step, sticking throughout
        assert (max(ratio) > 0.999) if regime == "sliding" else (0.01 < max(ratio) < 0.95), ratio
    perturbed = perturbations(mode, sim, kb, tb, tape, rng,
                              make=lambda m, **kw: contact_simulator(m, kind, mu, nu, **kw))
    checked = {k: perturbed[k] for k in ("dof0", "kappa_bar", "log_youngs_modulus", "gravity", "log_radius")}
    _check_tangents(tape, checked)
    # the contact's own parameters move the rod less (1e-5 to 1e-3 of these): larger steps in the study
    contact_params = {"log_contact_stiffness": ({"log_contact_stiffness": np.ones(B)}, lambda eps: final_dof(
        contact_simulator(mode, kind, mu, nu, k=1e4 * math.exp(eps)), kb, tb)),
        "log_contact_delta": ({"log_contact_delta": np.ones(B)}, lambda eps: final_dof(
            contact_simulator(mode, kind, mu, nu, delta=5e-3 * math.exp(eps)), kb, tb))}
    if mu > 0.0:
        contact_params["friction"] = ({"friction": np.ones(B)}, lambda eps: final_dof(
            contact_simulator(mode, kind, mu + eps, nu), kb, tb))
    _check_tangents(tape, contact_params, steps=(1e-3, 1e-4, 1e-5), smallest=1e-6)
    checked.update(contact_params)
    dp, dr = rng.normal(0.0, 1.0, (B, 1, 3)), rng.normal(0.0, 1.0, (B, 1, 3))  # the obstacle moved and turned
    pose_params = {"obstacle_position": ({"obstacle_position": dp}, lambda eps: posed_dof(sim, kb, tb, eps * dp)),
                   "obstacle_rotation": ({"obstacle_rotation": dr}, lambda eps: posed_dof(sim, kb, tb, None, eps * dr))}
    _check_tangents(tape, pose_params)
    checked.update(pose_params)
    _check_adjoint(tape, checked, rng)  # the adjoint through the contact is the tangent mode's transpose
    free = simulator(mode)  # the same rollout without the obstacle: different derivatives
    g = np.tile([0.3, 0.0, 0.5], (B, 1))
    jc = tape.jvp({"gravity": g})["dof"][-1]
    jf = G.rollout(free, start(free), controls(free, kb, tb)).jvp({"gravity": g})["dof"][-1]
    assert np.linalg.norm(jc - jf) > 1e-3 * np.linalg.norm(jf)


DRAG = DragSpec(normal=60.0, tangential=30.0, flow=(0.3, 0.0, 0.1))


def drag_simulator(mode: str, **kw) -> Simulator:
    """:func:`simulator` in a viscous fluid that flows across the rod."""
    return Simulator(build_model(dataclasses.replace(make_spec(**{**ROD, "mode": mode, **kw}), drag=DRAG)), envs=B)


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_tangents_through_viscous_drag_match_central_differences(mode):
    """Drag depends on the step's start as well (the velocity, and the tangent it takes at the start): the start
    columns are a band there. Tangents against central differences, the adjoint against the tangents, and the drag
    changes them."""
    rng = np.random.default_rng(2)
    sim = drag_simulator(mode)
    N = sim.model.node_count
    kb, tb = random_controls(mode, N, rng)
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    assert tape.unconverged == 0
    perturbed = perturbations(mode, sim, kb, tb, tape, rng, make=drag_simulator)
    checked = {k: perturbed[k] for k in ("dof0", "vel0", "kappa_bar", "gravity", "damping")}
    _check_tangents(tape, checked)
    _check_adjoint(tape, checked, rng)
    still = simulator(mode)
    v0 = checked["vel0"][0]
    jd = tape.jvp(v0)["dof"][-1]
    js = G.rollout(still, start(still), controls(still, kb, tb)).jvp(v0)["dof"][-1]
    assert np.linalg.norm(jd - js) > 1e-2 * np.linalg.norm(js)


MOVING = (FixSpec(nodes=(0, 1), velocity=(0.4, 0.1, -0.2), start=0.03, stop=0.09),  # the clamp carried, mid-rollout
          FixSpec(twist_edges=(0,), twist_rate=2.0))


def moving_simulator(mode: str, fluid: bool = False, **kw) -> Simulator:
    """:func:`simulator` with its clamp carried along (and twisted, 3-D) for part of the rollout; in the flowing
    fluid of :data:`DRAG` if ``fluid``."""
    fixes = MOVING if mode == "3d" else (dataclasses.replace(MOVING[0], axes="xz", velocity=(0.4, 0.0, -0.2)),)
    spec = make_spec(**{**ROD, "mode": mode, "clamp": "none", **kw})
    spec = dataclasses.replace(spec, fixes=fixes, **({"drag": DRAG} if fluid else {}))
    return Simulator(build_model(spec), envs=B)


@pytest.mark.parametrize("mode,fluid", [("2d", False), ("3d", False), ("2d", True), ("3d", True)])
def test_tangents_with_prescribed_motion_match_central_differences(mode, fluid):
    """A clamp carried at a velocity (and twisted at a rate) over part of the rollout: its DOFs are constants of each
    step, moved before it; each step is linearised from the DOFs it started from (in a fluid, whose drag lags the
    tangent at the step's start, from the moved clamp). Checked as the other cases, and the motion changes the
    derivatives."""
    rng = np.random.default_rng(3)
    sim = moving_simulator(mode, fluid)
    N = sim.model.node_count
    kb, tb = random_controls(mode, N, rng)
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    assert tape.unconverged == 0 and tape.moved is not None
    assert np.abs(tape.dof[-1, :, 2] - tape.dof[0, :, 2]).max() > 0.01  # the clamp moved
    perturbed = perturbations(mode, sim, kb, tb, tape, rng, make=lambda m, **kw: moving_simulator(m, fluid, **kw))
    checked = {k: perturbed[k] for k in ("dof0", "vel0", "kappa_bar", "gravity", "log_youngs_modulus")}
    _check_tangents(tape, checked)
    _check_adjoint(tape, checked, rng)
    held = Simulator(build_model(dataclasses.replace(make_spec(**{**ROD, "mode": mode, "clamp": "none"}), fixes=(
        dataclasses.replace(MOVING[0], velocity=(0.0, 0.0, 0.0)),), **({"drag": DRAG} if fluid else {}))), envs=B)
    g = checked["gravity"][0]
    jm = tape.jvp(g)["dof"][-1]
    jh = G.rollout(held, start(held), controls(held, kb, tb)).jvp(g)["dof"][-1]
    assert np.linalg.norm(jm - jh) > 1e-3 * np.linalg.norm(jh)


TURNING = FixSpec(nodes=(0, 1), twist_edges=(0,), angular_velocity=(0.5, 2.0, 1.0), center=(0.0, 0.0, 0.0),
                  start=0.02, stop=0.08)


def turning_simulator(mode: str, fluid: bool = False, **kw) -> Simulator:
    """:func:`simulator` with its clamp turned about the base for part of the rollout (3-D)."""
    spec = make_spec(**{**ROD, "mode": mode, "clamp": "none", **kw})
    spec = dataclasses.replace(spec, fixes=(TURNING,), **({"drag": DRAG} if fluid else {}))
    return Simulator(build_model(spec), envs=B)


@pytest.mark.parametrize("fluid", [False, True])
def test_tangents_with_a_turning_clamp_match_central_differences(fluid):
    """A clamp turned rigidly (its nodes, and its edge's angle so that its material frame turns with it) before each
    step of a window: each step is linearised from the state its kernel started from, the turn applied."""
    rng = np.random.default_rng(5)
    sim = turning_simulator("3d", fluid)
    kb, tb = random_controls("3d", sim.model.node_count, rng)
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    assert tape.unconverged == 0 and tape.moved is not None
    assert np.abs(tape.moved["dof"][2] - tape.dof[2]).max() > 1e-2  # the clamp turned (its nodes and edge angle)
    perturbed = perturbations("3d", sim, kb, tb, tape, rng, make=lambda m, **kw: turning_simulator(m, fluid, **kw))
    checked = {k: perturbed[k] for k in ("dof0", "vel0", "kappa_bar", "tau_bar", "gravity")}
    _check_tangents(tape, checked)
    _check_adjoint(tape, checked, rng)


def test_adjoint_is_the_transpose_of_the_tangent_mode(case):
    mode, sim, kb, tb, tape, rng = case
    grads = _check_adjoint(tape, perturbations(*case), rng, velocities=True)  # a loss over the whole trajectory
    assert not grads["log_contact_stiffness"].any() and not grads["friction"].any()  # no contact here


def test_envs_of_a_batch_are_differentiated_alone(case):
    """Env 1's derivatives do not depend on env 0's tangents (the envs are independent)."""
    mode, sim, kb, tb, tape, rng = case
    n = tape.dof.shape[2]
    v = np.zeros((B, n))
    v[0] = rng.normal(0.0, 0.1, n) * ~sim.kernel_rod.fixed.astype(bool)
    out = tape.jvp({"vel0": v})
    assert np.all(out["dof"][:, 1] == 0.0) and np.any(out["dof"][:, 0] != 0.0)


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_tangents_of_the_midpoint_rule_match_central_differences(mode):
    """Implicit midpoint: each step solves a backward-Euler residual over h/2 for the half-step point, and its end
    follows linearly (x' = 2 x½ − x, u' = 2 (x½ − x)/(h/2) − u; the end frames transported from the start); a step
    redone by backward Euler (it gained energy) is differentiated as such in its env. Every parameter against
    central differences, and the adjoint against the tangents."""
    rng = np.random.default_rng(4)
    make = lambda m, **kw: simulator(m, integrator="midpoint", **kw)  # noqa: E731
    sim = make(mode)
    N = sim.model.node_count
    kb, tb = random_controls(mode, N, rng)
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    assert tape.unconverged == 0 and np.all(tape.rule(0).beta == -1.0)
    fell = tape.fallback  # steps that gained energy, redone by backward Euler, among midpoint steps
    assert fell.any() and not fell.all()
    if mode == "3d":
        assert (fell[:, 0] != fell[:, 1]).any()  # on some step in one env alone
    perturbed = perturbations(mode, sim, kb, tb, tape, rng, make=make)
    _check_tangents(tape, perturbed)
    _check_adjoint(tape, perturbed, rng, velocities=True)


def test_what_is_not_covered_is_refused_by_name():
    spec = make_spec(nodes=8, direction=DIRECTION)
    pairs = dataclasses.replace(spec, contact=ContactSpec(self_contact=True, margin=1e-3, delta=5e-3))
    sim = Simulator(build_model(pairs), envs=B)
    with pytest.raises(G.GradientError, match="margin"):  # a pair in reach might not be found again
        G.rollout(sim, sim.reset(), [sim.make_control()])
    sim = simulator("2d")
    tape = G.rollout(sim, sim.reset(), [sim.make_control()])
    with pytest.raises(G.GradientError, match="unknown parameter 'stiffness'"):
        tape.jvp({"stiffness": np.ones(B)})
    with pytest.raises(G.GradientError, match="shape"):
        tape.jvp({"damping": np.ones(3)})
    with pytest.raises(G.GradientError, match="non-finite"):
        tape.vjp({"dof": np.full(tape.dof.shape[1:], np.nan)})


R_PAIR = 0.01  # the rods' radius in the edge-pair scenes; they start GAP apart (within the contact's δ = 5 mm)


def _pair_simulator(rods, mode: str, mu: float, nu: float, k: float = 1e4, delta: float = 5e-3, touch: bool = True,
                    **kw) -> Simulator:
    """Rods built by ``rods(base)`` (from the :data:`ROD` settings with ``kw``, 8 nodes of 0.6 m, radius
    :data:`R_PAIR`) with contact between edges (``touch``; rod–rod and self-contact), stiffness ``k``, distance
    ``delta``, friction ``mu`` with velocity tolerance ``nu`` and the default line search."""
    spec = make_spec(**{**ROD, "mode": mode, "line_search": "auto", "length": 0.6, "radius": R_PAIR, **kw})
    return Simulator(build_model(dataclasses.replace(spec, rods=rods(spec.rods[0]), contact=ContactSpec(
        stiffness=k, delta=delta, friction=mu, friction_velocity_tol=nu, rod_contact=touch, self_contact=touch))),
        envs=B)


def _crossing(base):
    """3-D: a rod clamped across a stiff one (1000 × E) just above it: gravity presses it on, mid-edge of both."""
    bottom = dataclasses.replace(base, name="bottom", start=(-0.3, 0.0, 0.0), direction=(1.0, 0.0, 0.0),
                                 youngs_modulus=1e3 * base.youngs_modulus)
    return bottom, dataclasses.replace(base, name="top", start=(0.0, -0.3, 2 * R_PAIR + GAP), direction=(0.0, 1.0, 0.0))


def _tip(base):
    """2-D: a rod clamped above a stiff one, leaning down at 45° so its tip sits just above the stiff one's middle."""
    bottom = dataclasses.replace(base, name="bottom", start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0),
                                 youngs_modulus=1e3 * base.youngs_modulus)
    d = np.array([-1.0, 0.0, -1.0]) / math.sqrt(2.0)
    tip = np.array([0.3, 0.0, 2 * R_PAIR + GAP])
    return bottom, dataclasses.replace(base, name="top", start=tuple(tip - 0.6 * d), direction=tuple(d))


def _loop(base):
    """3-D self-contact: one rod that runs along x, turns and crosses over its own first part just above it (that
    part stiff, 1000 × E), clamped at its start."""
    h = 2 * R_PAIR + GAP
    pts = [(x, 0.0, 0.0) for x in (0.0, 0.125, 0.25, 0.375, 0.5)] + [(0.56, 0.12, 0.3 * h), (0.45, 0.24, 0.7 * h),
                                                                      (0.32, 0.27, h)]
    pts += [(0.2, y, h) for y in (0.25, 0.15, 0.05, -0.05, -0.15)]
    E = base.youngs_modulus
    return (dataclasses.replace(base, nodes=len(pts), rest_points=tuple(pts),
                                edge_youngs_modulus=tuple([1e3 * E] * 4 + [E] * (len(pts) - 5))),)


def _clamp_on_rod(base):
    """3-D: a rod sagging onto another's clamped first edge, which lies across it just under its middle (the rest of
    the other rod out over the side): the pair at the clamp holds the rod up, so a move of the clamp moves it."""
    top = dataclasses.replace(base, name="top", start=(-0.3, 0.0, 0.0), direction=(1.0, 0.0, 0.0))
    return top, dataclasses.replace(base, name="under", start=(0.0, -0.04, -(2 * R_PAIR + GAP)),
                                    direction=(0.0, 1.0, 0.0))


PAIR_SCENES = {"crossing": ("3d", _crossing), "tip": ("2d", _tip), "loop": ("3d", _loop)}
PAIR_CASES = [("crossing", regime) for regime in FRICTION] + [("tip", "frictionless"), ("tip", "sliding"),
                                                               ("loop", "frictionless"), ("loop", "sliding")]


@pytest.mark.parametrize("scene,regime", PAIR_CASES)
def test_tangents_through_contact_between_edges_match_central_differences(scene, regime):
    """Contact between edges (docs/physics.md §4.8): a rod pressed across another (3-D, without friction, sliding and
    sticking), a rod's tip on another (2-D) and a rod crossing over itself (self-contact). The pairs couple DOFs far
    apart along the chain: J is the band plus a low-rank term solved by the Woodbury identity. Every step has the
    pairs in touch in every env; the tangents match central differences, the adjoint is their transpose, and
    without the contact the derivatives differ."""
    mode, rods = PAIR_SCENES[scene]
    mu, nu = FRICTION[regime]
    make = lambda m, **kw: _pair_simulator(rods, mode, mu, nu, **kw)  # noqa: E731
    rng = np.random.default_rng(1)
    sim = make(mode)
    kb, tb = (0.2 * a for a in random_controls(mode, sim.model.node_count, rng))  # small: the rods stay in touch
    ctrls = controls(sim, kb, tb)
    tape = G.rollout(sim, start(sim), ctrls)
    assert tape.unconverged == 0
    assert all(sorted(tape._linear(k, ()).low) == list(range(B)) for k in range(T))  # pairs in touch, every step
    st, ratio = start(sim), []
    for c in ctrls:
        last = sim.step(st, c)
        ratio += [np.linalg.norm(last.contact_friction_force[e, :k], axis=-1).sum()
                  / (max(mu, 1e-300) * last.contact_normal_force[e, :k].sum())
                  for e, k in enumerate(last.contact_count) if k > 0]
    if mu > 0.0:  # the friction law's branch: sliding on some step, sticking throughout
        assert (max(ratio) > 0.999) if regime == "sliding" else (0.01 < max(ratio) < 0.95), ratio
    perturbed = perturbations(mode, sim, kb, tb, tape, rng, make=make)
    checked = {k: perturbed[k] for k in ("dof0", "vel0", "kappa_bar", "log_youngs_modulus", "gravity", "log_radius")}
    _check_tangents(tape, checked)
    contact_params = {"log_contact_stiffness": ({"log_contact_stiffness": np.ones(B)}, lambda eps: final_dof(
        make(mode, k=1e4 * math.exp(eps)), kb, tb)),
        "log_contact_delta": ({"log_contact_delta": np.ones(B)}, lambda eps: final_dof(
            make(mode, delta=5e-3 * math.exp(eps)), kb, tb))}
    if mu > 0.0:
        contact_params["friction"] = ({"friction": np.ones(B)}, lambda eps: final_dof(
            _pair_simulator(rods, mode, mu + eps, nu), kb, tb))
    _check_tangents(tape, contact_params, steps=(1e-3, 1e-4, 1e-5), smallest=1e-6)
    checked.update(contact_params)
    _check_adjoint(tape, checked, rng)
    apart = _pair_simulator(rods, mode, mu, nu, touch=False)
    g = np.tile([0.3, 0.0, 0.5], (B, 1))
    jc = tape.jvp({"gravity": g})["dof"][-1]
    ja = G.rollout(apart, start(apart), controls(apart, kb, tb)).jvp({"gravity": g})["dof"][-1]
    assert np.linalg.norm(jc - ja) > 1e-3 * np.linalg.norm(ja)


HELD_SCENES = {  # a change of the constrained DOFs too (the clamp moved): they keep it and move the rest
    "2-D": lambda: simulator("2d"), "3-D": lambda: simulator("3d"),
    "3-D sliding on a sphere": lambda: contact_simulator("3d", "sphere", *FRICTION["sliding"]),
    "3-D, clamp carried in a fluid": lambda: moving_simulator("3d", True),
    "3-D, a clamped edge on another rod": lambda: _pair_simulator(_clamp_on_rod, "3d", *FRICTION["frictionless"]),
    "3-D, a clamped edge sliding on another rod": lambda: _pair_simulator(_clamp_on_rod, "3d", *FRICTION["sliding"]),
}


@pytest.mark.parametrize("name", HELD_SCENES)
def test_a_change_of_the_clamp_is_kept_and_moves_the_rod(name):
    """dof0 on the constrained DOFs: the clamp moved (and, 3-D, turned about the rod's axis through its twist
    angle). A constrained DOF keeps its change through every step (J's columns there, kept aside, move the others).
    Moving the whole rod without obstacles moves every state by the same (translation invariance, exact); a random
    change of every DOF, clamp included, against central differences; the adjoint against the tangents."""
    sim = HELD_SCENES[name]()
    mode = sim.model.mode
    rng = np.random.default_rng(8)
    kb, tb = random_controls(mode, sim.model.node_count, rng)
    if "clamped edge" in name:
        kb, tb = 0.2 * kb, 0.2 * tb  # small: the clamped edge stays on the other rod
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    if "clamped edge" in name:  # the pair at the clamp in touch every step, in every env
        st = start(sim)
        for c in controls(sim, kb, tb):
            assert np.all(sim.step(st, c).contact_count > 0)
    n = tape.dof.shape[2]
    fixed = sim.kernel_rod.fixed.astype(bool)
    pos = np.ones(n, bool) if mode == "2d" else (np.arange(n) % 4 != 3)
    d = np.array([0.3, -0.2, 0.5]) if mode == "3d" else np.array([0.3, 0.5])
    shift = np.zeros((B, n))
    shift[:, pos] = np.tile(d, n // (4 if mode == "3d" else 2))
    if tape.contact is None:
        moved = tape.jvp({"dof0": shift})["dof"]
        assert np.allclose(moved, shift[None], atol=1e-9), np.abs(moved - shift[None]).max()
    x0 = rng.normal(0.0, 0.01, (B, n))
    x0[:, fixed & ~pos] *= 10.0  # the clamp's twist angle (3-D): a roll of its material frame
    if mode == "3d":
        x0[:, n - 1] = 0.0  # the last node's dummy angle
    tangent = {"dof0": x0}
    checked = {"dof0 (clamp too)": (tangent, lambda eps: final_dof(sim, kb, tb, dof0=tape.dof[0] + eps * x0))}
    assert np.abs(x0[:, fixed]).max() > 0
    _check_tangents(tape, checked)
    _check_adjoint(tape, checked, rng)


def test_a_change_of_a_turned_clamp_is_refused():
    sim = turning_simulator("3d")
    tape = G.rollout(sim, start(sim), controls(sim, *random_controls("3d", sim.model.node_count,
                                                                       np.random.default_rng(0))))
    x0 = np.zeros((B, tape.dof.shape[2]))
    x0[:, 0] = 1.0  # node 0: the clamp's
    with pytest.raises(G.GradientError, match="turned about a centre"):
        tape.jvp({"dof0": x0})
    grad = tape.vjp({"dof": np.ones(tape.dof.shape[1:])}, params=("dof0",))["dof0"]  # nor a gradient there
    fixed = sim.kernel_rod.fixed.astype(bool)
    assert not grad[:, fixed].any() and grad[:, ~fixed].any()


SPLIT = {  # Newton capped so that the retry ladder splits steps: in one env of two (2 sub-steps), in both (up to 16)
    "3-D, one env split": dict(mode="3d", max_iter=5),
    "3-D, both split": dict(mode="3d", max_iter=4),
    "2-D": dict(mode="2d", max_iter=3),
    "3-D midpoint": dict(mode="3d", max_iter=5, integrator="midpoint"),
}


@pytest.mark.parametrize("name", SPLIT)
def test_tangents_through_the_retry_ladders_sub_steps_match_central_differences(name):
    """A step whose Newton solve fails is taken as 2, 4, … sub-steps (docs/physics.md §6): the rollout takes the
    sub-steps again from the step's start with the ladder's own sub-step (bit for bit), and the derivatives chain
    through them, env by env (an env whose step was not split, or whose sub-steps are over, is left as it is by the
    parts after its last)."""
    kw = dict(SPLIT[name])
    mode = kw.pop("mode")
    make = lambda m, **k2: simulator(m, tol=1e-10, dtol=1e-10, **{**kw, **k2})  # noqa: E731
    rng = np.random.default_rng(0)
    sim = make(mode)
    kb, tb = random_controls(mode, sim.model.node_count, rng)
    tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
    split = [sorted(tape.subs[k]) for k in range(T)]
    assert tape.subs is not None and max(tape.parts(k) for k in range(T)) > 1, split
    perturbed = perturbations(mode, sim, kb, tb, tape, rng, make=make)
    _check_tangents(tape, perturbed)
    _check_adjoint(tape, perturbed, rng, velocities=True)
    every = G.rollout(sim, start(sim), controls(sim, kb, tb), checkpoint=2)  # the sub-steps taken again there too
    g = perturbed["gravity"][0]
    assert np.array_equal(every.jvp(g)["dof"], tape.jvp(g)["dof"])


CHECKPOINTED = {  # scenes whose records take every path of a step: contact with friction, turned frames, drag, rules
    "sliding on a sphere": lambda: contact_simulator("3d", "sphere", *FRICTION["sliding"]),
    "a rod sliding across another": lambda: _pair_simulator(_crossing, "3d", *FRICTION["sliding"]),
    "a clamp turned in a fluid": lambda: turning_simulator("3d", True),
    "a clamp carried, 2-D": lambda: moving_simulator("2d"),
    "midpoint, 2-D": lambda: simulator("2d", integrator="midpoint"),
}


@pytest.mark.parametrize("name", CHECKPOINTED)
def test_a_checkpointed_rollout_gives_the_full_tapes_derivatives(name):
    """``rollout(checkpoint=K)`` keeps the state every K steps and steps again from it when a pass needs the states
    between (each segment once per pass): its records, tangents and gradients are the full tape's to the bit, for
    K = 1, a K that does not divide T, and K = T."""
    rng = np.random.default_rng(6)
    sim = CHECKPOINTED[name]()
    mode, N = sim.model.mode, sim.model.node_count
    kb, tb = random_controls(mode, N, rng)
    full = G.rollout(sim, start(sim), controls(sim, kb, tb))
    n = full.dof.shape[2]
    free = ~sim.kernel_rod.fixed.astype(bool)
    tangents = [{"dof0": rng.normal(0.0, 0.01, (B, n)) * free}, {"kappa_bar": random_controls(mode, N, rng)[0]},
                {"gravity": rng.normal(0.0, 1.0, (B, 3)), "damping": np.ones(B)}]
    cot = {"dof": rng.normal(0.0, 1.0, (T + 1, B, n)), "vel": rng.normal(0.0, 1.0, (B, n))}
    want_t, want_g = full.jvp(tangents), full.vjp(cot)
    for every in (1, 2, T):
        tape = G.rollout(sim, start(sim), controls(sim, kb, tb), checkpoint=every)
        assert tape.unconverged == full.unconverged
        assert np.array_equal(tape.dof[:, 1], full.dof[:, 1]) and np.array_equal(tape.vel[-1], full.vel[-1])
        segments = -(-T // every)
        before = tape._replay.replays
        got_g = tape.vjp(cot)
        # each segment stepped again once per pass (the last one may still be held from reading the records)
        assert segments - 1 <= tape._replay.replays - before <= segments
        got_t = tape.jvp(tangents)
        for key in want_t:
            assert np.array_equal(got_t[key], want_t[key]), (every, key)
        for key in want_g:
            assert np.array_equal(got_g[key], want_g[key]), (every, key)
        assert not any(isinstance(k, tuple) for k in tape._lin)  # no linearisation kept between passes


def test_a_checkpointed_rollout_keeps_a_fraction_of_the_states():
    """A 40-step rollout checkpointed every 8 steps keeps 5 states (and the controls) instead of 41 records."""
    sim = simulator("3d")
    steps = 40
    ctrls = [sim.make_control() for _ in range(steps)]
    full = G.rollout(sim, start(sim), ctrls)
    kept = G.rollout(sim, start(sim), ctrls, checkpoint=8)
    controls_bytes = full.kappa_bar.nbytes + full.tau_bar.nbytes
    assert kept.nbytes - controls_bytes < 0.25 * (full.nbytes - controls_bytes)
    with pytest.raises(G.GradientError, match="checkpoint must be"):
        G.rollout(sim, start(sim), ctrls, checkpoint=0)


def test_an_objective_on_a_material_frame_has_the_gradient_of_central_differences():
    """L = Σ W ∘ R over the last edge's material frame of the final state and of a middle state: its gradient with
    respect to the natural curvature and twist, by one adjoint pass with the frame's "dof" and "phi" cotangents,
    against central differences of whole rollouts (the twist and the directors' transport both move R)."""
    rng = np.random.default_rng(7)
    sim = simulator("3d")
    N = sim.model.node_count
    kb, tb = random_controls("3d", N, rng)
    tb *= 4.0  # twisted, so the directors turn about the tangents as well as with them
    W = {T: rng.normal(size=(B, 3, 3)), 2: rng.normal(size=(B, 3, 3))}

    def objective(kb, tb):
        tape = G.rollout(sim, start(sim), controls(sim, kb, tb))
        return tape, sum(np.sum(w * tape.material_frame(k, -1), axis=(1, 2)) for k, w in W.items())

    tape, _ = objective(kb, tb)
    E = tape.ref_d1.shape[2]
    cot = {"dof": np.zeros(tape.dof.shape), "phi": np.zeros((T + 1, B, E))}
    for k, w in W.items():
        dof, phi = tape.frame_cotangents(k, -1, w)
        cot["dof"][k] += dof
        cot["phi"][k] += phi
    grads = tape.vjp(cot, params=("kappa_bar", "tau_bar"))
    dk, dt = rng.normal(size=kb.shape), rng.normal(size=tb.shape)
    want = np.einsum("tbnc,tbnc->b", grads["kappa_bar"], dk) + np.einsum("tbn,tbn->b", grads["tau_bar"], dt)
    errors = {}
    for eps in (1e-4, 1e-5):
        fd = (objective(kb + eps * dk, tb + eps * dt)[1] - objective(kb - eps * dk, tb - eps * dt)[1]) / (2 * eps)
        errors[eps] = np.abs(fd - want).max() / np.abs(fd).max()
    assert min(errors.values()) <= 1e-6, errors
    without = tape.vjp({"dof": cot["dof"]}, params=("tau_bar",))["tau_bar"]  # the directors' turn left out
    assert np.abs(np.einsum("tbn,tbn->b", without - grads["tau_bar"], dt)).max() > 1e-4 * np.abs(fd).max()


def test_a_frame_cotangent_is_refused_for_a_planar_rod_and_an_unknown_one_by_name():
    sim = simulator("2d")
    tape = G.rollout(sim, start(sim), controls(sim, *random_controls("2d", sim.model.node_count,
                                                                      np.random.default_rng(0))))
    with pytest.raises(G.GradientError, match="planar"):
        tape.vjp({"phi": np.zeros((B, sim.model.node_count - 1))})
    with pytest.raises(G.GradientError, match="planar"):
        tape.material_frame(T)
    with pytest.raises(G.GradientError, match="unknown cotangent 'theta'"):
        tape.vjp({"theta": np.zeros(1)})
