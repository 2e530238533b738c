"""rodlab simulator: batched implicit Discrete-Elastic-Rod time-stepping (numba).

Public surface::

    from sim import load_scene, build_model, Simulator
    spec = load_scene("assets/scenes/arm.toml"); model = build_model(spec)
    sim = Simulator(model, envs=B); state = sim.reset(); ctrl = sim.make_control()
    stats = sim.step(state, ctrl)

Loads and constrained nodes: ``SceneSpec(loads=(LoadSpec(...),), fixes=(FixSpec(...),))`` (sim.scene.boundary); static
equilibrium: ``sim.analysis.static.solve_static(spec, state, ctrl)``. Several rods: ``SceneSpec(sim, rods=(RodSpec(...,
name="a"), RodSpec(..., name="b")))`` (``[[rod]]`` tables in a file): one chain of nodes in that order;
``model.split_rods(state.node_pos)`` -> {name: (B, n_rod, 3)}, ``model.rod_slices()`` -> {name: slice}, fixes and
loads name their ``rod`` (docs/physics.md §1.7).

Derivatives of a rollout (tangent and adjoint modes, docs/physics.md §3.9): ``tape = sim.analysis.gradients.rollout(sim,
state, controls)``; ``tape.jvp({...})``, ``tape.vjp({...})``.

Compiling the kernels ahead of time: ``python -m sim.warmup`` (not imported here, so running it as a module is clean).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from sim._cache import invalidate_if_sources_changed as _invalidate
from sim.support.lazy import lazy_face

_invalidate()  # before any kernel module loads its numba cache

# The public names load on first use (PEP 562), so importing a light package (sim.support, sim.geometry, sim.scene)
# does not load the step and its numba kernels. Code outside sim imports this face, the faces of sim.scene,
# sim.geometry, sim.analysis and sim.contact, and the modules of sim.support; never another module of sim
# (tests/test_import_graph.py).
_LAZY = {"FixSpec": "sim.scene", "LoadSpec": "sim.scene", "Model": "sim.scene", "build_model": "sim.scene",
         "RodSpec": "sim.scene", "SceneError": "sim.scene", "SceneSpec": "sim.scene", "SimSpec": "sim.scene",
         "dump_scene": "sim.scene", "load_scene": "sim.scene", "parse_scene": "sim.scene",
         "Control": "sim.state", "State": "sim.state", "StepStats": "sim.state", "STATE_FLOAT_ARRAYS": "sim.state",
         "Simulator": "sim.step", "compile_kernels": "sim.warmup"}

__all__ = ["load_scene", "parse_scene", "dump_scene", "SceneError", "SceneSpec", "SimSpec", "RodSpec", "Model",
           "build_model", "Simulator", "State", "Control", "StepStats", "STATE_FLOAT_ARRAYS", "LoadSpec", "FixSpec",
           "compile_kernels"]

if TYPE_CHECKING:
    from sim.scene import (
        FixSpec,
        LoadSpec,
        Model,
        RodSpec,
        SceneError,
        SceneSpec,
        SimSpec,
        build_model,
        dump_scene,
        load_scene,
        parse_scene,
    )
    from sim.state import STATE_FLOAT_ARRAYS, Control, State, StepStats
    from sim.step import Simulator
    from sim.warmup import compile_kernels


__getattr__, __dir__ = lazy_face(__name__, _LAZY)
