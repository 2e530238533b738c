"""rodlab simulator: batched implicit Discrete-Elastic-Rod time-stepping (numba).

Public surface::

    from sim import load_scene, build_model, Simulator
    spec = load_scene("assets/scenes/arm.toml"); model = build_model(spec)
    sim = Simulator(model, envs=B); state = sim.reset(); ctrl = sim.make_control()
    stats = sim.step(state, ctrl)

Loads and constrained nodes: ``SceneSpec(loads=(LoadSpec(...),), fixes=(FixSpec(...),))`` (sim.boundary); static
equilibrium: ``sim.static.solve_static(spec, state, ctrl)``. Several rods: ``SceneSpec(sim, rods=(RodSpec(...,
name="a"), RodSpec(..., name="b")))`` (``[[rod]]`` tables in a file): one chain of nodes in that order;
``model.split_rods(state.node_pos)`` -> {name: (B, n_rod, 3)}, ``model.rod_slices()`` -> {name: slice}, fixes and
loads name their ``rod`` (docs/physics.md §1.7).

Derivatives of a rollout (tangent and adjoint modes, docs/physics.md §3.9): ``tape = sim.gradients.rollout(sim,
state, controls)``; ``tape.jvp({...})``, ``tape.vjp({...})``.

Compiling the kernels ahead of time: ``python -m sim.warmup`` (not imported here, so running it as a module is clean).
"""
from ._cache import invalidate_if_sources_changed as _invalidate

_invalidate()

from .boundary import FixSpec, LoadSpec  # noqa: E402
from .model import Model, build_model  # noqa: E402
from .scene import RodSpec, SceneError, SceneSpec, SimSpec, dump_scene, load_scene, parse_scene  # noqa: E402
from .state import Control, State, StepStats  # noqa: E402
from .step import Simulator  # noqa: E402

__all__ = ["load_scene", "parse_scene", "dump_scene", "SceneError", "SceneSpec", "SimSpec", "RodSpec", "Model",
           "build_model", "Simulator", "State", "Control", "StepStats", "LoadSpec", "FixSpec"]
