"""Helpers to build SceneSpecs in code for the sim tests."""
from __future__ import annotations

from dataclasses import replace

from sim.scene.spec import RodSpec, SceneSpec, SimSpec


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


def small_scene_toml(rod_lines: str) -> str:
    """A five-node rod scene as TOML text ([sim] at rest, no gravity; [rod] along +x) with ``rod_lines`` (the keys
    under test, e.g. per-edge lists or a pre-stretch) added to its [rod] table; keys given there replace the
    defaults."""
    rod = {"nodes": "5", "length": "1.0", "radius": "0.01", "density": "1000", "youngs_modulus": "1e6",
           "poisson_ratio": "0.5", "start": "[0, 0, 0]", "direction": "[1, 0, 0]"}
    extra = [ln for ln in rod_lines.strip().splitlines() if ln.strip()]
    for ln in extra:
        rod.pop(ln.split("=")[0].strip(), None)
    lines = ["[sim]", "dt = 0.01", "gravity = [0, 0, 0]", "newton_tol = 1e-8", "newton_max_iter = 20",
             "accept_unconverged = false", "[rod]"] + [f"{k} = {v}" for k, v in rod.items()] + extra
    return "\n".join(lines) + "\n"


#: the paper's arm as a scene document (assets/scenes/arm.toml's rod and solver settings)
ARM = """
[sim]
dt = 0.05
gravity = [0.0, 0.0, -9.8]
newton_tol = 1e-3
newton_max_iter = 2
accept_unconverged = true

[rod]
nodes = 21
length = 1.0
radius = 0.05
density = 1000.0
youngs_modulus = 1e7
poisson_ratio = 0.5
start = [0.0, 0.0, 0.0]
direction = [0.0, 0.0, 1.0]
"""
