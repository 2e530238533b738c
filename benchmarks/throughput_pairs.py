"""The ``pairs`` part of ``rodlab bench throughput``: what self-contact and rod–rod contact cost
(docs/physics.md §4.8).

* two rods 0.5 m apart on a floor with ``rod_contact`` off and on: the cost of the switch when no pair is near
  (the broad phase's boxes only), as a ratio measured in the same run;
* the paper's arm (sinusoidal command) with ``self_contact`` off and on: its edges are 5 cm long, so pairs a few
  edges apart are within the 5 cm broad-phase margin and are candidates (their distance is tested at every
  Newton iteration) although they never touch;
* a rod curled 1.25 turns resting on itself (self-contact active in every env): cost and Newton iterations
  against the same rod curled to 0.75 turn (no contact);
* two rods, one lying across the other on a floor (rod–rod contact active in every env), against the same rods
  placed apart;
* a long rod (201 nodes, 1 cm edges) hanging as a cantilever with ``self_contact`` off and on: nothing touches,
  but the ~850 pairs a few edges apart inside the 5 cm margin are candidates, tested at every Newton iteration.

Every figure is the median of several repeats of a few steps; CPU time is reported beside wall time.
"""
from __future__ import annotations

import time

import numpy as np

from .common import load
from .rodlab_runs import Solver, make_sim
from .throughput_timing import arm_doc, time_sim

CURL_NODES = 41


def _curl_doc(self_contact: bool) -> dict:
    return {
        "sim": {"dt": 0.01, "gravity": [0.0, 0.0, 0.0], "damping": 5.0, "newton_tol": 1e-6, "newton_max_iter": 30,
                "accept_unconverged": True},
        "rod": {"nodes": CURL_NODES, "length": 1.0, "radius": 0.02, "density": 1000.0, "youngs_modulus": 1e6,
                "poisson_ratio": 0.5, "start": [0.0, 0.0, 0.0], "direction": [1.0, 0.0, 0.0]},
        "contact": {"stiffness": 1e5, "delta": 2e-3, "self_contact": self_contact},
    }


def two_rod_doc(*, apart: bool, rod_contact: bool = True) -> dict:
    """A rod on a floor and a second rod across it (dropped from 5 mm above), or 0.5 m away from it."""
    y0 = 1.0 if apart else 0.0
    rod = {"nodes": 21, "length": 1.0, "radius": 0.01, "density": 1000.0, "youngs_modulus": 1e6,
           "poisson_ratio": 0.5, "clamp": "none"}
    return {
        "sim": {"dt": 0.01, "gravity": [0.0, 0.0, -9.81], "damping": 2.0, "newton_tol": 1e-6, "newton_max_iter": 30,
                "accept_unconverged": True},
        "rod": [dict(rod, name="bottom", start=[-0.5, 0.0, 0.0101], direction=[1.0, 0.0, 0.0]),
                dict(rod, name="top", start=[0.0, y0 - 0.5, 0.035], direction=[0.0, 1.0, 0.0])],
        "obstacle": [{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}],
        "contact": {"stiffness": 1e5, "delta": 1e-3, "rod_contact": rod_contact},
    }


def _time_steps(doc: dict, *, envs: int, repeats: int, steps: int, settle: int, command=None) -> dict:
    """Median wall/CPU ms per batched step after ``settle`` steps (``command(ctrl, k)`` sets the control)."""
    sim, state, ctrl = make_sim(doc, envs=envs)
    k = [0]
    iters: list[float] = []

    def one():
        if command is not None:
            command(ctrl, k[0])
        st = sim.step(state, ctrl)
        iters.append(float(np.mean(st.newton_iters)))
        k[0] += 1
        return st

    for _ in range(settle):
        one()
    iters.clear()
    ts, cs = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(steps):
            st = one()
        ts.append((time.perf_counter() - t0) / steps)
        cs.append((time.process_time() - c0) / steps)
    return {"envs": envs, "ms_per_step": 1e3 * float(np.median(ts)), "cpu_ms_per_step": 1e3 * float(np.median(cs)),
            "iters_mean": float(np.mean(iters)), "failed_envs": int(np.sum(state.failed)),
            "contact_energy_mean": float(np.mean(st.energy_contact)), "nan": int(np.sum(~np.isfinite(state.dof))),
            "repeats": repeats, "steps": steps, "load": load()}


def _hanging_doc(self_contact: bool) -> dict:
    return {
        "sim": {"dt": 0.01, "gravity": [0.0, 0.0, -9.81], "damping": 2.0, "newton_tol": 1e-6, "newton_max_iter": 30,
                "accept_unconverged": True},
        "rod": {"nodes": 201, "length": 2.0, "radius": 0.005, "density": 1000.0, "youngs_modulus": 1e7,
                "poisson_ratio": 0.5, "start": [0.0, 0.0, 1.0], "direction": [1.0, 0.0, 0.0]},
        "contact": {"stiffness": 1e5, "delta": 1e-3, "self_contact": self_contact},
    }


def _curl_command(turns: float):
    total = 2 * np.pi * turns

    def command(ctrl, k):
        ctrl.kappa_bar[:, 1:-1, 0] = min(1.0, (k + 1) / 150) * total / (CURL_NODES - 2)
    return command


def part_pairs(*, quick: bool, repeats: int) -> dict:
    B = 20 if quick else 100
    out: dict = {"envs": B}
    solver = Solver(tol=1e-3, max_iter=5)
    off = time_sim(arm_doc(solver=solver), envs=B, repeats=repeats)
    on = time_sim(arm_doc(solver=solver, contact={"self_contact": True}), envs=B, repeats=repeats)
    out["arm_self_contact_off"], out["arm_self_contact_on_nothing_near"] = off, on
    out["ratio_self_contact_on_over_off"] = on["ms_per_step"] / off["ms_per_step"]
    out["ratio_self_contact_on_over_off_cpu"] = on["cpu_ms_per_step"] / off["cpu_ms_per_step"]
    print(f"  arm, self_contact off (B={B}): {off['ms_per_step']:8.3f} ms/step (CPU {off['cpu_ms_per_step']:8.3f}); "
          f"on, nothing near: {on['ms_per_step']:8.3f} (CPU {on['cpu_ms_per_step']:8.3f}) -> ratio "
          f"{out['ratio_self_contact_on_over_off']:.3f}", flush=True)
    steps = 5 if quick else 10
    for name, turns in (("curl_0.75_turn_no_contact", 0.75), ("curl_1.25_turns_resting_on_itself", 1.25)):
        r = _time_steps(_curl_doc(True), envs=B, repeats=repeats, steps=steps, settle=300,
                        command=_curl_command(turns))
        out[name] = r
        print(f"  {name:36s} (B={B}): {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f}) "
              f"it {r['iters_mean']:.2f} contact energy {r['contact_energy_mean']:.2e} J failed {r['failed_envs']}",
              flush=True)
    for name, apart, rc in (("two_rods_apart_rod_contact_off", True, False), ("two_rods_apart", True, True),
                            ("two_rods_crossed_resting", False, True)):
        r = _time_steps(two_rod_doc(apart=apart, rod_contact=rc), envs=B, repeats=repeats, steps=steps, settle=100)
        out[name] = r
        print(f"  {name:36s} (B={B}): {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f}) "
              f"it {r['iters_mean']:.2f} contact energy {r['contact_energy_mean']:.2e} J failed {r['failed_envs']}",
              flush=True)
    for name, sc in (("hanging_201_self_contact_off", False), ("hanging_201_self_contact_on", True)):
        r = _time_steps(_hanging_doc(sc), envs=max(B // 5, 4), repeats=repeats, steps=steps, settle=3)
        out[name] = r
        print(f"  {name:36s} (B={r['envs']}): {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f}) "
              f"it {r['iters_mean']:.2f} failed {r['failed_envs']}", flush=True)
    out["ratio_rod_contact_on_over_off_apart"] = (out["two_rods_apart"]["ms_per_step"]
                                                  / out["two_rods_apart_rod_contact_off"]["ms_per_step"])
    out["ratio_rod_contact_on_over_off_apart_cpu"] = (out["two_rods_apart"]["cpu_ms_per_step"]
                                                      / out["two_rods_apart_rod_contact_off"]["cpu_ms_per_step"])
    print(f"  rod_contact on / off, rods apart: {out['ratio_rod_contact_on_over_off_apart']:.3f} "
          f"(CPU {out['ratio_rod_contact_on_over_off_apart_cpu']:.3f})", flush=True)
    return out
