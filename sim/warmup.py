"""Compile (or load from the numba cache) the kernels on a tiny model: ``python -m sim.warmup``. Besides the step
kernels, the static solve's Hessian (sim.analysis.hessian, the stability check) and the rollout derivatives' linearisation
(sim.analysis.gradients), so a first ``rodlab sim --static`` or ``rodlab fit`` does not wait for them."""
from __future__ import annotations

import sys
import time
from typing import Callable

import numpy as np

from sim.analysis.gradients import rollout
from sim.analysis.static import solve_static
from sim.contact.world import spec_contact_data
from sim.kernels.probe import pair_linearisation, pair_residual, substeps_at
from sim.scene.model import build_model
from sim.scene.spec import RodSpec, SceneSpec, SimSpec
from sim.step import Simulator

__all__ = ["compile_kernels", "STAGES"]

STAGES = 4  # kernel groups compiled by warmup: the step, then the static Hessian and derivatives, in 3-D and in 2-D


def _tiny_spec(mode: str):
    return SceneSpec(
        sim=SimSpec(dt=0.01, gravity=(0.0, 0.0, -9.8), newton_tol=1e-3, newton_max_iter=2, accept_unconverged=True,
                    mode=mode),  # type: ignore[arg-type]
        rod=RodSpec(nodes=5, length=0.4, radius=0.01, density=1000.0, youngs_modulus=1e6, poisson_ratio=0.5,
                    start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0)))


def compile_kernels(*, verbose: bool = False, on_stage: Callable[[str], None] | None = None) -> float:
    """Compile/load the 3-D and 2-D kernels; returns the seconds it took. ``on_stage(what)`` is called before each
    of the :data:`STAGES` kernel groups with what is compiled next and how far along that is ("… (stage k of 4)";
    the workbench shows it while the page waits)."""
    t0 = time.perf_counter()
    k = 0

    def stage(what: str) -> None:
        nonlocal k
        k += 1
        if on_stage is not None:
            on_stage(f"{what} (stage {k} of {STAGES})")

    for mode in ("3d", "2d"):
        stage(f"the {mode.upper()} step kernel")
        if verbose:
            print(f"sim.warmup: compiling the {mode} step kernel (first run only; cached afterwards)...",
                  file=sys.stderr, flush=True)
        spec = _tiny_spec(mode)
        sim = Simulator(build_model(spec), envs=2)
        state = sim.reset()
        sim.step(state, sim.make_control())
        stage(f"the {mode.upper()} static Hessian and derivatives")
        if verbose:
            print(f"sim.warmup: compiling the {mode} static Hessian and rollout derivatives...", file=sys.stderr,
                  flush=True)
        solve_static(spec, state, sim.make_control(), max_steps=2)   # the stability check's Hessian
        tape = rollout(sim, sim.reset(), [sim.make_control()])          # the step's linearisation
        tape.jvp({"kappa_bar": np.zeros_like(tape.kappa_bar)})
        x, x0 = (np.ascontiguousarray(tape.dof[i, 0]) for i in (1, 0))  # the edge pairs' part, without pairs
        n = x.size
        pair_residual(sim.kernel_params, sim.kernel_rod, x, x0, spec.sim.dt, np.empty(n))
        pair_linearisation(sim.kernel_params, sim.kernel_rod, x, x0, spec.sim.dt, 1e-7, True, True,
                           np.empty(n, np.int64), np.empty((n, n)), np.empty((n, n)))
        m, st, ctrl = sim.model, sim.reset(), sim.make_control()  # the retry ladder's sub-steps taken again
        E, N = m.node_count - 1, m.node_count
        substeps_at(0, x0, np.ascontiguousarray(st.dof_vel.reshape(2, -1)[0]), st.edge_ref_d1[0].copy(),
                    st.edge_tangent[0].copy(), st.node_ref_twist[0].copy(), ctrl.kappa_bar[0].copy(),
                    ctrl.tau_bar[0].copy(), 2, sim.kernel_rod._replace(grav=np.ascontiguousarray(tape.grav[0])),
                    sim.kernel_params, spec_contact_data(m.obstacles, 1, N, m.edge_radius, candidates=0),
                    np.empty((3, n)), np.empty((3, n)), np.empty((3, E, 3)), np.empty((3, E, 3)), np.empty((3, N)),
                    np.zeros(2, np.int64))
    return time.perf_counter() - t0


def main() -> int:
    dt = compile_kernels(verbose=True)
    print(f"sim.warmup: kernels ready in {dt:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
