"""Helpers to build SceneSpecs in code for the sim tests."""
from __future__ import annotations

from dataclasses import replace

from sim.scene import RodSpec, SceneSpec, SimSpec


def make_spec(*, nodes=11, length=1.0, radius=0.02, density=1000.0, E=1e6, nu=0.5, start=(0.0, 0.0, 0.0),
              direction=(1.0, 0.0, 0.0), clamp="first_edge", dt=0.01, gravity=(0.0, 0.0, 0.0), tol=1e-10,
              max_iter=50, accept=False, mode="3d", integrator="backward_euler", line_search="none", damping=0.0,
              dtol=1e-9) -> SceneSpec:
    """A SceneSpec with tight Newton settings (for verification; override as needed)."""
    return SceneSpec(
        sim=SimSpec(dt=dt, gravity=gravity, newton_tol=tol, newton_max_iter=max_iter, accept_unconverged=accept,
                    damping=damping, mode=mode, integrator=integrator, line_search=line_search, newton_dtol=dtol),
        rod=RodSpec(nodes=nodes, length=length, radius=radius, density=density, youngs_modulus=E, poisson_ratio=nu,
                    start=start, direction=direction, clamp=clamp))


def with_sim(spec: SceneSpec, **kw) -> SceneSpec:
    return replace(spec, sim=replace(spec.sim, **kw))
