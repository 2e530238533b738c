"""The models added for issue #36 against closed forms and reference values: a stepped (non-uniform) cantilever,
friction under the tasks' Newton budget (a rod on an incline, a rope over a drum), the buckled column reached by
``to_stable``, resistive-force drag, an end moment and a line load, the clamp at a node, a rotating clamp and the
internal loads.

Each case is the set-up of its verification test (tests/sim/test_nonuniform.py, contact/test_friction_newton.py,
test_static_stability.py, test_drag.py, test_loads.py, test_exact_clamp.py, test_rotating_clamp.py,
test_internal_loads.py), copied here; the script prints one line per figure (the error and the test's bound) and
writes them as JSON.

    .venv/bin/python -m benchmarks.accuracy_models --out docs/bench/accuracy_models.json
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import brentq
from scipy.special import ellipk

from benchmarks.common import machine_info, write_json
from benchmarks.references import heavy_elastica
from sim import Simulator, build_model, parse_scene
from sim.analysis import solve_static
from sim.geometry import matrix_from_rotvec
from sim.scene import DragSpec, FixSpec, LineLoadSpec, LoadSpec, RodSpec, SceneSpec, SimSpec

COMMAND = "python -m benchmarks.accuracy_models"


def _spec(*, nodes=11, length=1.0, radius=0.02, density=1000.0, E=1e6, nu=0.5, direction=(1.0, 0.0, 0.0),
          clamp="first_edge", dt=0.01, gravity=(0.0, 0.0, 0.0), tol=1e-10, max_iter=50, mode="3d", damping=0.0,
          dtol=1e-9) -> SceneSpec:
    """A one-rod scene from the origin with tight Newton settings (no line search), as the verification tests
    build them."""
    return SceneSpec(sim=SimSpec(dt=dt, gravity=gravity, newton_tol=tol, newton_max_iter=max_iter,
                                 accept_unconverged=False, damping=damping, mode=mode, line_search="none",
                                 newton_dtol=dtol),
                     rod=RodSpec(nodes=nodes, length=length, radius=radius, density=density, youngs_modulus=E,
                                 poisson_ratio=nu, start=(0.0, 0.0, 0.0), direction=direction, clamp=clamp))


def _row(case: str, figure: str, value: float, bound: float, unit: str = "", **extra: Any) -> dict[str, Any]:
    """One printed figure: ``value`` (an error, or a ratio of errors) and the bound its test asserts on |value|
    (or, for a pair, the interval)."""
    return {"case": case, "figure": figure, "value": float(value), "bound": bound, "unit": unit, **extra}


def _within(r: dict[str, Any]) -> bool:
    b, v = r["bound"], r["value"]
    if b is None:
        return True
    if isinstance(b, (list, tuple)):
        return b[0] <= v <= b[1]
    return abs(v) <= b


def _relaxed(spec: SceneSpec):
    """(sim, state, ctrl) at the static equilibrium of ``spec`` (sim.analysis.static, as the tests relax them)."""
    sim = Simulator(build_model(spec), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    res = solve_static(spec, st, ctrl, xtol=1e-13, check_stability=False, max_steps=400)
    assert res.converged.all()
    return sim, st, ctrl


def _stepped_static(spec: SceneSpec, steps: int = 3):
    """Large backward-Euler steps to equilibrium (tests/helpers/statics.static_solve)."""
    sim = Simulator(build_model(spec), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    for _ in range(steps):
        stats = sim.step(st, ctrl)
    assert stats.converged.all()
    return sim, st


# --- stepped (non-uniform) cantilever: tests/sim/test_nonuniform.py --------------------------------------------

def stepped_cantilever(Ns=(21, 41, 81)) -> list[dict[str, Any]]:
    """Radius 20 mm on [0, 0.5], 10 mm beyond (EI ratio 16), E = 1e7, tip load 1e-5 N: the relative tip-deflection
    error against the two-segment beam formula δ = F/3 ((L³ − (L−a)³)/EI_a + (L−a)³/EI_b), built-in end at the
    middle of edge 0; second order in the edge length."""
    R_ROOT, R_TIP, E, F = 0.02, 0.01, 1e7, 1e-5
    EIa, EIb = E * np.pi * R_ROOT ** 4 / 4, E * np.pi * R_TIP ** 4 / 4
    errs = []
    for N in Ns:
        s = np.linspace(0.0, 1.0, N)
        mid = 0.5 * (s[:-1] + s[1:])
        spec = _spec(nodes=N, radius=R_ROOT, E=E, dt=1e4, dtol=1e-14, max_iter=100)
        spec = dataclasses.replace(spec, rod=dataclasses.replace(
            spec.rod, edge_radius=tuple(float(R_ROOT if m < 0.5 else R_TIP) for m in mid)),
            loads=(LoadSpec(node=-1, force=(0.0, 0.0, -F)),))
        sim, st = _stepped_static(spec)
        p = st.node_pos[0]
        tip = p[-1] - 0.5 * (p[0] + p[1])
        x0 = 0.5 * sim.model.rest_edge_length[0]
        L, a = 1.0 - x0, 0.5 - x0
        ref = F / 3.0 * ((L ** 3 - (L - a) ** 3) / EIa + (L - a) ** 3 / EIb)
        errs.append((-tip[2] - ref) / ref)
    rows = [_row("stepped_cantilever", f"stepped cantilever, N = {N}: tip deflection, relative error", e,
                 1e-3 if N == 41 else None, nodes=N) for N, e in zip(Ns, errs)]
    for i in range(len(Ns) - 1):
        rows.append(_row("stepped_cantilever", f"stepped cantilever: error ratio N = {Ns[i]} / {Ns[i + 1]}",
                         errs[i] / errs[i + 1], [3.5, 4.5] if Ns[i + 1] == 2 * Ns[i] - 1 else None))
    return rows


# --- friction under the Newton budget: tests/sim/contact/test_friction_newton.py -------------------------------

_FR_R = 0.01
_FR_ROD = dict(nodes=11, length=0.5, radius=_FR_R, density=1000.0, youngs_modulus=1e7, poisson_ratio=0.5,
               start=[0.0, 0.0, 0.0], direction=[1.0, 0.0, 0.0], clamp="none")
_NU = 1e-2  # friction_velocity_tol (the [contact] default)


def incline(iters: int, steps: int = 200) -> list[dict[str, Any]]:
    """A free rod across a 20° incline, μ = 0.5 (it must stick: μ > tan 20°), released 4 mm inside the contact
    layer, ``iters`` Newton iterations a step, unconverged iterates accepted, the default line search: the settled
    velocity (mean of the last 50 steps) against the regularised stick law's creep v_c = (2ν/15) artanh(tan α/μ)
    down the slope, its step-to-step spread, the fastest motion up the slope, and the friction force along the
    slope over W sin α."""
    a = math.radians(20.0)
    n = np.array([-math.sin(a), 0.0, math.cos(a)])
    up = np.array([math.cos(a), 0.0, math.sin(a)])
    doc = {"sim": dict(dt=0.01, gravity=[0.0, 0.0, -9.8], newton_tol=1e-6, newton_max_iter=iters,
                       accept_unconverged=True),
           "rod": dict(_FR_ROD, start=list((_FR_R + 4e-3) * n), direction=[0.0, 1.0, 0.0]),
           "obstacle": [dict(type="plane", point=[0, 0, 0], normal=list(n))], "contact": dict(friction=0.5)}
    sim = Simulator(build_model(parse_scene(doc, None)), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    W = float(sim.model.node_mass.sum() * 9.8)
    v, f = [], []
    for _ in range(steps):
        s = sim.step(st, ctrl)
        v.append(float(np.mean(st.node_vel[0] @ up)))
        k = int(s.contact_count[0])
        f.append(float(s.contact_friction_force[0, :k].sum(0) @ up))
    v_c = (2.0 * _NU / 15.0) * math.atanh(math.tan(a) / 0.5)
    late = np.array(v[-50:])
    case = f"incline_{iters}_iterations"
    head = f"incline 20°, μ = 0.5, {iters} Newton iterations"
    return [_row(case, f"{head}: creep velocity / v_c − 1 (v_c = {v_c * 1e3:.3f} mm/s down)",
                 -late.mean() / v_c - 1.0, 0.05, creep_m_s=-float(late.mean()), v_creep_m_s=v_c),
            _row(case, f"{head}: creep spread (max − min of the last 50 steps) / v_c", np.ptp(late) / v_c, 0.05),
            _row(case, f"{head}: fastest motion up the slope", max(0.0, max(v)), 1e-6, "m/s"),
            _row(case, f"{head}: friction force / (W sin α) − 1", np.mean(f[-50:]) / (W * math.sin(a)) - 1.0, 0.02,
                 friction_N=float(np.mean(f[-50:])), w_sin_alpha_N=W * math.sin(a))]


def capstan_scene() -> tuple[Simulator, float]:
    """The capstan case's simulator (one env) and the radius the rope's centre line is draped at [m]: a light rope
    (r = 2 mm, ρ = 100) over a capsule drum (R = 5 cm, wrap π, μ = 0.3), end loads T1 = 0.1 N and
    T2 = 0.8 e^{μπ} T1, 30 Newton iterations, unconverged iterates accepted."""
    mu, Rd, r, H = 0.3, 0.05, 0.002, 0.2
    rc = Rd + r + 1e-3
    pts = [(-rc, 0.0, z) for z in np.linspace(-H, 0.0, 21)[:-1]]
    pts += [(rc * math.cos(t), 0.0, rc * math.sin(t)) for t in np.linspace(math.pi, 0.0, 17)[:-1]]
    pts += [(rc, 0.0, z) for z in np.linspace(0.0, -H, 21)]
    t1 = 0.1
    t2 = 0.8 * math.exp(mu * math.pi) * t1
    doc = {"sim": dict(dt=0.01, gravity=[0.0, 0.0, -9.8], newton_tol=1e-6, newton_max_iter=30,
                       accept_unconverged=True),
           "rod": dict(rest_points=[list(p) for p in pts], radius=r, density=100.0, youngs_modulus=1e7,
                       poisson_ratio=0.5, clamp="none"),
           "obstacle": [dict(type="capsule", start=[0, -0.1, 0], end=[0, 0.1, 0], radius=Rd)],
           "contact": dict(friction=mu),
           "load": [dict(node=0, force=[0, 0, -t1]), dict(node=len(pts) - 1, force=[0, 0, -t2])]}
    return Simulator(build_model(parse_scene(doc, None)), envs=1), rc


def capstan(seconds: float = 5.0) -> list[dict[str, Any]]:
    """A light rope (r = 2 mm, ρ = 100) draped over a capsule drum (R = 5 cm, wrap π, μ = 0.3), end loads
    T1 = 0.1 N and T2 = 0.8 e^{μπ} T1 (below the capstan limit), 30 Newton iterations, unconverged iterates
    accepted: how far the heavy end slips over ``seconds`` (the regularised stick law's creep, about 1 mm/s; the
    test's bound is 5 mm over 3 s, scaled here with the time), the largest slip in one step (an isolated kick would
    show there: 1–5 cm before friction entered the first iterate), and how far the rope's top node is off the
    drum."""
    sim, rc = capstan_scene()
    N = sim.model.node_count
    st, ctrl = sim.reset(), sim.make_control()
    z0 = st.node_pos[0, -1, 2]
    finite, step_slip, z = True, 0.0, z0
    for _ in range(int(round(seconds / 0.01))):
        sim.step(st, ctrl)
        finite &= bool(np.all(np.isfinite(st.dof)))
        step_slip = max(step_slip, abs(float(z - st.node_pos[0, -1, 2])))
        z = st.node_pos[0, -1, 2]
    slip = float(z0 - z)
    top = st.node_pos[0, N // 2]
    head = f"capstan, μ = 0.3, wrap π, T2/T1 = 0.8 e^(μπ), {seconds:g} s"
    return [_row("capstan", f"{head}: slip of the heavy end", slip, [0.0, 5e-3 * seconds / 3.0], "m",
                 finite=finite, seconds_simulated=seconds),
            _row("capstan", f"{head}: largest slip in one step", step_slip, None, "m"),
            _row("capstan", f"{head}: top of the rope off the drum", math.hypot(top[0], top[2]) - rc, 2e-3, "m")]


# --- the buckled column: tests/sim/analysis/test_static_stability.py -----------------------------------------------------

def buckled_column(N: int = 41) -> list[dict[str, Any]]:
    """A clamped column (r = 2 cm, E = 1e7, L = 1) under twice its Euler load P_cr = π² EI/(4 L'²), lateral
    imperfection 1e-4 at the tip, solved statically with ``to_stable``: the lateral tip deflection against the
    clamped-free elastica's δ = 2k/√(P/EI), K(k) = √(P/EI) L' (L' from the middle of the clamped edge), over L'."""
    R, E = 0.02, 1e7
    EI = E * np.pi * R ** 4 / 4
    lf = 1.0 - 0.5 / (N - 1)
    p_cr = np.pi ** 2 * EI / (4 * lf ** 2)
    spec = dataclasses.replace(_spec(nodes=N, radius=R, E=E, dt=5e-3),
                               loads=(LoadSpec(node=-1, force=(-2.0 * p_cr, 0.0, 0.0)),))
    sim = Simulator(build_model(spec), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    st.dof[:, :, 2] = 1e-4 * np.linspace(0.0, 1.0, N) ** 2
    saddle = solve_static(spec, st, ctrl)
    res = solve_static(spec, st, ctrl, to_stable=True)
    assert res.converged.all()
    p = st.node_pos[0]
    tip = p[-1] - 0.5 * (p[0] + p[1])
    alpha = np.sqrt(2.0 * p_cr / EI)
    k = brentq(lambda k: ellipk(k * k) - alpha * lf, 1e-9, 1.0 - 1e-12)
    ref = 2.0 * k / alpha
    got = float(np.hypot(tip[1], tip[2]))
    return [_row("buckled_column", f"column at 2 P_cr, N = {N}, to_stable: tip deflection error / L' "
                 f"({got:.5f} m against the elastica's {ref:.5f} m)", (got - ref) / lf, 1e-3,
                 tip_deflection_m=got, elastica_m=ref,
                 negative_directions_before=int(saddle.negative_directions[0]),
                 negative_directions_after=int(res.negative_directions[0]), stable=bool(res.stable[0]))]


# --- resistive-force drag: tests/sim/test_drag.py ---------------------------------------------------------------

_CT = 2.0
_CN = 2.0 * _CT


def sedimentation(angles=(0.0, 90.0, 45.0), steps: int = 400) -> list[dict[str, Any]]:
    """A free straight rod (N = 11, L = 0.5, r = 1 cm, E = 1e6) at an angle φ to the horizontal sinking under its
    weight W with c_n = 2 c_t = 4 N s/m², 4 s (≈ 25 time constants): every node's velocity against RFT's
    V = (1/L)[t̂t̂ᵀ/c_t + (I − t̂t̂ᵀ)/c_n] W, the largest difference over |V|."""
    rows = []
    for ang in angles:
        a = math.radians(ang)
        t = np.array([math.cos(a), 0.0, math.sin(a)])
        spec = dataclasses.replace(_spec(nodes=11, length=0.5, radius=0.01, E=1e6, clamp="none",
                                         direction=tuple(t), gravity=(0.0, 0.0, -9.81)),
                                   drag=DragSpec(normal=_CN, tangential=_CT))
        sim = Simulator(build_model(spec), envs=1)
        st, ctrl = sim.reset(), sim.make_control()
        for _ in range(steps):
            sim.step(st, ctrl)
        W = np.array([0.0, 0.0, -9.81 * float(sim.model.node_mass.sum())])
        V = (np.outer(t, t) / _CT + (np.eye(3) - np.outer(t, t)) / _CN) @ W / 0.5
        err = float(np.abs(st.node_vel[0] - V).max() / np.linalg.norm(V))
        rows.append(_row("sedimentation", f"sedimentation at {ang:g}° (RFT {np.linalg.norm(V) * 1e3:.2f} mm/s): "
                         "velocity error / |V|", err, 1e-6, angle_deg=ang))
    return rows


def cross_flow(N: int = 21) -> list[dict[str, Any]]:
    """A cantilever (L = 1, r = 2 cm, E = 1e7) at rest in a uniform cross-flow U = 2 cm/s, c_n = 2 c_t = 4: the tip
    deflection against q L'⁴/(8 EI), q = c_n U, relative."""
    U = 0.02
    spec = dataclasses.replace(_spec(nodes=N, radius=0.02, E=1e7, dt=1e4, dtol=1e-14, max_iter=100),
                               drag=DragSpec(normal=_CN, tangential=_CT, flow=(0.0, 0.0, U)))
    sim, st, _ = _relaxed(spec)
    c = st.node_pos[0]
    Lf = 1.0 - 0.5 * sim.model.rest_edge_length[0]
    expect = _CN * U * Lf ** 4 / (8 * sim.model.EI1_max)
    got = c[-1, 2] - 0.5 * (c[0, 2] + c[1, 2])
    return [_row("cross_flow", f"clamped rod in a cross-flow, N = {N}: tip deflection / (q L⁴/8EI) − 1",
                 got / expect - 1.0, 2e-2)]


# --- end moment and line load: tests/sim/test_loads.py ----------------------------------------------------------

def end_moment(Ns=(21, 41)) -> list[dict[str, Any]]:
    """A cantilever (L = 1, r = 2 cm, E = 1e7) with a couple M = EI/L' about −y on its tip (one radian of turning):
    the tip's distance from the circular arc of curvature M/EI from the clamp's effective end [m]; second order."""
    R, E = 0.02, 1e7
    errs = []
    for N in Ns:
        EI = E * np.pi * R ** 4 / 4
        Lf = 1.0 - 0.5 / (N - 1)
        M = EI / Lf
        spec = dataclasses.replace(_spec(nodes=N, radius=R, E=E, dt=1e4, dtol=1e-14, max_iter=100),
                                   loads=(LoadSpec(node=-1, moment=(0.0, -M, 0.0)),))
        _, st, _ = _relaxed(spec)
        p = st.node_pos[0]
        kappa = M / EI
        arc = np.array([np.sin(kappa * Lf) / kappa, 0.0, (1 - np.cos(kappa * Lf)) / kappa])
        errs.append(float(np.linalg.norm(p[-1] - 0.5 * (p[0] + p[1]) - arc)))
    rows = [_row("end_moment", f"end moment (circular arc, 1 rad), N = {N}: tip distance from the arc", e,
                 2e-3 if N == Ns[-1] else None, "m", nodes=N) for N, e in zip(Ns, errs)]
    for i in range(len(Ns) - 1):
        rows.append(_row("end_moment", f"end moment: error ratio N = {Ns[i]} / {Ns[i + 1]}", errs[i] / errs[i + 1],
                         [3.0, 5.0]))
    return rows


def node_clamp(Ns=(11, 21, 41, 81)) -> list[dict[str, Any]]:
    """A cantilever (L = 1, E = 1e7) built in at node 1 (``clamp = "node"``, docs/physics.md §3.6): the relative
    error of a small tip force's deflection (r = 2 cm) against F L_f³/(3 EI) and the tip's distance from the
    extensible elastica's under P L_f²/EI = 3 (r = 2 mm, as the test, whose reference is inextensible: axial strain
    3e-6), both from node 1 over the free length L_f = L − l̄; second order in the edge length
    (tests/sim/test_exact_clamp.py)."""
    E = 1e7
    small, large = [], []
    for N in Ns:
        Lf = 1.0 - 1.0 / (N - 1)
        for r, errs in ((0.02, small), (0.002, large)):
            EI = E * np.pi * r ** 4 / 4
            P = 1e-3 if errs is small else 3.0 * EI / Lf ** 2
            spec = dataclasses.replace(_spec(nodes=N, radius=r, E=E, dtol=1e-14, max_iter=100, clamp="node"),
                                       loads=(LoadSpec(node=-1, force=(0.0, 0.0, -P)),))
            _, st, _ = _relaxed(spec)
            tip = st.node_pos[0, -1] - st.node_pos[0, 1]
            if errs is small:
                ref = P * Lf ** 3 / (3 * EI)
                errs.append((-tip[2] - ref) / ref)
            else:
                ref = heavy_elastica(length=Lf, EI=EI, w=0.0, P=P, EA=E * np.pi * r * r)
                errs.append(float(np.hypot(tip[0] - ref.x[-1], tip[2] - ref.z[-1])))
    rows = []
    for name, errs, unit, bound in (("tip force F L_f³/3EI: relative error", small, "", 2e-3),
                                    ("elastica tip (P L_f²/EI = 3): distance", large, "m", 5e-4)):
        rows += [_row("node_clamp", f"clamp at node 1, N = {N}: {name}", e, bound if N == Ns[-1] else None, unit,
                      nodes=N) for N, e in zip(Ns, errs)]
        rows += [_row("node_clamp", f"clamp at node 1, {name.split(':')[0]}: error ratio N = {a} / {b}",
                      ea / eb, [3.48, 4.59] if name.startswith("tip") else [3.25, 100.0])
                 for a, b, ea, eb in zip(Ns[:-1], Ns[1:], errs[:-1], errs[1:])]
    return rows


def line_load(N: int = 21) -> list[dict[str, Any]]:
    """A cantilever (L = 1, r = 2 cm, E = 1e7) under a uniform line load q = 1e-3 N/m (−z): the tip deflection
    against q L'⁴/(8 EI), relative."""
    q = 1e-3
    spec = dataclasses.replace(_spec(nodes=N, radius=0.02, E=1e7, dt=1e4, dtol=1e-14, max_iter=100),
                               line_loads=(LineLoadSpec(force_per_length=(0.0, 0.0, -q)),))
    sim, st, _ = _relaxed(spec)
    p = st.node_pos[0]
    Lf = 1.0 - 0.5 * sim.model.rest_edge_length[0]
    expect = q * Lf ** 4 / (8 * sim.model.EI1_max)
    got = -(p[-1, 2] - 0.5 * (p[0, 2] + p[1, 2]))
    return [_row("line_load", f"uniform line load, N = {N}: tip deflection / (q L⁴/8EI) − 1", got / expect - 1.0,
                 2e-2)]


# --- rotating clamp and internal loads: tests/sim/test_rotating_clamp.py, test_internal_loads.py ---------------

def rotating_clamp(steps: int = 100) -> list[dict[str, Any]]:
    """A stiff rod (N = 11, L = 0.5, E = 1e9, damping 5) whose clamp (nodes 0, 1 and edge 0's twist) turns at
    ω = π/2 rad/s about z through node 0 for 1 s: the clamp's nodes against the rigid rotation of their start [m],
    its material frame against the turned one."""
    w = 0.5 * math.pi
    spec = dataclasses.replace(
        _spec(nodes=11, length=0.5, radius=0.01, E=1e9, clamp="none", dt=0.01, damping=5.0),
        fixes=(FixSpec(nodes=(0, 1), twist_edges=(0,), angular_velocity=(0.0, 0.0, w), stop=steps * 0.01),))
    sim = Simulator(build_model(spec), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    x0 = st.node_pos[0].copy()
    m1_0, m2_0, _ = (a[0, 0].copy() for a in sim.material_frames(st))
    for _ in range(steps):
        sim.step(st, ctrl)
    R = matrix_from_rotvec([0.0, 0.0, w * steps * 0.01])
    m1, m2, _ = (a[0, 0] for a in sim.material_frames(st))
    head = f"rotating clamp, {w * steps * 0.01 / math.pi * 180:g}° about z"
    return [_row("rotating_clamp", f"{head}: clamp nodes off the rigid rotation",
                 np.abs(st.node_pos[0, :2] - x0[:2] @ R.T).max(), 1e-14, "m"),
            _row("rotating_clamp", f"{head}: clamped edge's material frame off the turned one",
                 max(np.abs(m1 - R @ m1_0).max(), np.abs(m2 - R @ m2_0).max()), 1e-12)]


def internal_loads() -> list[dict[str, Any]]:
    """A rod (N = 11, r = 1 cm, E = 1e6) clamped at the top and hanging under gravity: each edge's axial force
    against the weight below it; a cantilever (N = 21, E = 1e7) under a tip load P = 0.05 N (≈ 19 % deflection):
    the bending moment at the interior nodes against P times the deformed lever arm. Largest relative errors."""
    hang = _spec(nodes=11, radius=0.01, E=1e6, direction=(0.0, 0.0, -1.0), gravity=(0.0, 0.0, -9.81), dt=1e3,
                 dtol=1e-14, max_iter=100)
    sim, st, ctrl = _relaxed(hang)
    below = 9.81 * np.cumsum(sim.model.node_mass[::-1])[::-1][1:]
    axial = sim.internal_loads(st, ctrl).axial[0, 1:]
    e_axial = float(np.abs(axial / below[1:] - 1.0).max())
    P, n = 0.05, 21
    cant = dataclasses.replace(_spec(nodes=n, radius=0.01, E=1e7, dt=1e3, dtol=1e-14, max_iter=100),
                               loads=(LoadSpec(node=n - 1, force=(0.0, 0.0, -P)),))
    sim, st, ctrl = _relaxed(cant)
    x = st.node_pos[0]
    inner = slice(2, n - 1)
    lever = x[-1, 0] - x[inner, 0]
    bend = np.abs(sim.internal_loads(st, ctrl).bending[0, inner, 1])
    e_bend = float(np.abs(bend / (P * lever) - 1.0).max())
    return [_row("internal_loads", "hanging rod: axial force / weight below − 1 (largest over the edges)", e_axial,
                 1e-9),
            _row("internal_loads", f"cantilever, tip load, {-x[-1, 2]:.3f} L deflection: bending moment / "
                 "(P × lever arm) − 1 (largest)", e_bend, 1e-3)]


#: name -> (full run, smallest run: the smoke test's)
CASES: dict[str, tuple[Callable[[], list], Callable[[], list]]] = {
    "stepped_cantilever": (stepped_cantilever, lambda: stepped_cantilever((21, 41, 81))),
    "incline_2": (lambda: incline(2), lambda: incline(2)),
    "incline_3": (lambda: incline(3), lambda: incline(3)),
    "capstan": (capstan, lambda: capstan(3.0)),
    "buckled_column": (buckled_column, buckled_column),
    "sedimentation": (sedimentation, lambda: sedimentation((45.0,))),
    "cross_flow": (cross_flow, cross_flow),
    "end_moment": (end_moment, end_moment),
    "line_load": (line_load, line_load),
    "node_clamp": (node_clamp, lambda: node_clamp((21, 41))),
    "rotating_clamp": (rotating_clamp, rotating_clamp),
    "internal_loads": (internal_loads, internal_loads),
}


def run(names=None, *, quick: bool = False, echo: Callable[[str], None] | None = print) -> list[dict[str, Any]]:
    """Run the named cases (all by default) and return their rows (each with ``within``: inside the test's
    bound), printing one line per row."""
    rows = []
    for name in names or CASES:
        t0 = time.perf_counter()
        out = CASES[name][1 if quick else 0]()
        dt = time.perf_counter() - t0
        for r in out:
            r["within"] = _within(r)
            r["seconds"] = dt
            if echo:
                b = r["bound"]
                bound = ("—" if b is None else f"[{b[0]:.3g}, {b[1]:.3g}]" if isinstance(b, (list, tuple))
                         else f"≤ {b:.0e}")
                unit = f" {r['unit']}" if r["unit"] else ""
                echo(f"{r['figure']}: {r['value']:+.3e}{unit} (bound {bound}){'' if r['within'] else '  OUTSIDE'}")
        rows.extend(out)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.accuracy_models", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="write the figures to this JSON file")
    ap.add_argument("--quick", action="store_true", help="the smallest sizes (the smoke test's)")
    ap.add_argument("--cases", help=f"comma-separated subset of {', '.join(CASES)}")
    a = ap.parse_args(argv)
    names = a.cases.split(",") if a.cases else None
    bad = [n for n in names or () if n not in CASES]
    if bad:
        ap.error(f"unknown case {bad[0]!r}; known: {', '.join(CASES)}")
    info = machine_info()
    t0 = time.perf_counter()
    rows = run(names, quick=a.quick)
    total = time.perf_counter() - t0
    outside = sum(not r["within"] for r in rows)
    print(f"{len(rows)} figures, {outside} outside their test's bound, {total:.1f} s")
    if a.out:
        cmd = COMMAND + (" --quick" if a.quick else "") + (f" --cases {a.cases}" if a.cases else "") + f" --out {a.out}"
        write_json(a.out.parent, a.out.name, {"command": cmd, "machine": info, "seconds": total, "rows": rows})
    return 1 if outside else 0


if __name__ == "__main__":
    sys.exit(main())
