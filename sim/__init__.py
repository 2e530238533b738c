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
from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

from ._cache import invalidate_if_sources_changed as _invalidate

_invalidate()  # before any kernel module loads its numba cache

# The public names load on first use (PEP 562), so importing a light submodule (sim.support, sim.rotations,
# sim.scene) does not load the step and its numba kernels.
_PUBLIC = {"FixSpec": ".boundary", "LoadSpec": ".boundary", "Model": ".model", "build_model": ".model",
           "RodSpec": ".scene", "SceneError": ".scene", "SceneSpec": ".scene", "SimSpec": ".scene",
           "dump_scene": ".scene", "load_scene": ".scene", "parse_scene": ".scene", "Control": ".state",
           "State": ".state", "StepStats": ".state", "Simulator": ".step"}

__all__ = ["load_scene", "parse_scene", "dump_scene", "SceneError", "SceneSpec", "SimSpec", "RodSpec", "Model",
           "build_model", "Simulator", "State", "Control", "StepStats", "LoadSpec", "FixSpec"]

if TYPE_CHECKING:
    from .boundary import FixSpec, LoadSpec
    from .model import Model, build_model
    from .scene import RodSpec, SceneError, SceneSpec, SimSpec, dump_scene, load_scene, parse_scene
    from .state import Control, State, StepStats
    from .step import Simulator


def __getattr__(name: str):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'sim' has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
