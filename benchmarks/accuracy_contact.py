"""Accuracy scene ``contact``: the paper arm pressed into a fixed cylinder (scenes.ArmPress).

Error = max_t |tip - tip_ref(t)| / L against a converged rodlab run (many nodes, small dt, converged
Newton); also the max penetration [m] (rodlab: StepStats.max_penetration, i.e. past the contact
surface; PyElastica: rod radius + cylinder radius - centreline distance, sampled every 0.05 s).
The two simulators use different contact laws (IMC smooth barrier with δ = 5 mm vs a linear penalty
spring k = 1.6e5 N/m with damping ν = 4): the converged-vs-converged tip distance is reported as
the model gap.
"""
from __future__ import annotations

import time

import numpy as np

from . import accuracy_sweeps as sw
from . import rodlab_runs as rr
from .references import trajectory_error
from .rodlab_runs import CONVERGED
from .scenes import ArmPress


def bench(*, quick: bool, peer: bool, repeats: int) -> dict | None:
    sc = ArmPress()
    g = dict(sw.grids(quick))
    g["solvers"] = ["conv", "it5"] + ([] if quick else ["paper"])
    g["small_dt_solvers"] = ["conv"]
    ref_n, ref_dt = (41, 1e-3) if quick else (81, 2e-4)
    if sw.PEER_ONLY:
        if peer:
            from .peers import elastica_scenes as es
            kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
            g2 = dict(g)
            g2["el_nodes"] = [21] if quick else [11, 21, 41]
            sw.run_elastica_sweep("contact", es.run_arm, sc, g2, lambda r, n: {"error": None}, kw, repeats)
        return None
    t0 = time.perf_counter()
    ref = rr.run_arm(sc, n_nodes=ref_n, dt=ref_dt, solver=CONVERGED, sample_dt=0.01)
    ref2 = rr.run_arm(sc, n_nodes=ref_n, dt=2 * ref_dt, solver=CONVERGED, sample_dt=0.01)
    ref_t, ref_tip = np.asarray(ref["t"]), np.asarray(ref["tip"])
    change = trajectory_error(ref2["t"], ref2["tip"], ref_t, ref_tip, scale=sc.length)
    print(f"contact: reference N={ref_n} dt={ref_dt:g} in {time.perf_counter() - t0:.1f} s, max penetration "
          f"{1e3 * ref['max_penetration']:.2f} mm, |ref(2dt)-ref(dt)| = {change:.2e} L", flush=True)

    def err(r, n):
        return {"error": trajectory_error(r["t"], r["tip"], ref_t, ref_tip, scale=sc.length),
                "max_penetration": r.get("max_penetration")}

    pts = sw.run_rodlab_sweep("contact", rr.run_arm, sc, g, err, repeats)
    out = {"scene": "contact", "params": {k: v for k, v in vars(sc).items()},
           "reference": {"nodes": ref_n, "dt": ref_dt, "dt_doubling_change": change,
                         "max_penetration": ref["max_penetration"]},
           "error_definition": "max_t |tip - tip_ref(t)| / L, tip_ref = converged rodlab run (arm pressed "
                               "into a cylinder)"}
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        g2 = dict(g)
        g2["el_nodes"] = [21] if quick else [11, 21, 41]
        pts += sw.run_elastica_sweep("contact", es.run_arm, sc, g2, err, kw, repeats)
        dt_ref = es.stable_dt_estimate(es.RodSpec(n_nodes=41, **kw)) * 0.5
        key = f"contact_ref|41|{dt_ref:.6e}"
        eref = sw.PEER_CACHE.get(key) or es.run_arm(sc, n_nodes=41, dt=dt_ref, sample_dt=0.01)
        sw.PEER_CACHE[key] = eref
        out["model_gap"] = {"elastica_nodes": 41, "elastica_dt": dt_ref,
                            "max_tip_distance_over_L": trajectory_error(eref["t"], eref["tip"], ref_t, ref_tip,
                                                                        scale=sc.length),
                            "elastica_max_penetration": eref["max_penetration"],
                            "note": "different contact laws (IMC barrier vs penalty spring), shear, clamp"}
        print(f"  model gap {out['model_gap']['max_tip_distance_over_L']:.3g} L; PyElastica penetration "
              f"{1e3 * eref['max_penetration']:.2f} mm", flush=True)
    out["points"] = pts
    return out
