"""Scenes: a TOML file <-> the frozen :class:`SceneSpec` (rods, obstacles, loads, fixes, drag, contact), its checks
(every number bounded and finite, :mod:`sim.scene.validate`; warnings such as a rod starting inside an obstacle), and
the frozen :class:`Model` built from it (per-edge sections and stiffnesses, rest shape, boundary conditions,
obstacle geometry). docs/physics.md §1 defines the quantities.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {
    "DragSpec": "sim.scene.boundary",
    "FixSpec": "sim.scene.boundary",
    "LineLoadSpec": "sim.scene.boundary",
    "LoadSpec": "sim.scene.boundary",
    "global_node": "sim.scene.boundary",
    "node_index": "sim.scene.boundary",
    "overlap_warning": "sim.scene.check",
    "rod_obstacle_overlaps": "sim.scene.check",
    "Model": "sim.scene.model",
    "build_model": "sim.scene.model",
    "BoxSpec": "sim.scene.obstacles",
    "CapsuleSpec": "sim.scene.obstacles",
    "ContactSpec": "sim.scene.obstacles",
    "CylinderSpec": "sim.scene.obstacles",
    "MeshSpec": "sim.scene.obstacles",
    "PlaneSpec": "sim.scene.obstacles",
    "SphereSpec": "sim.scene.obstacles",
    "RodSpec": "sim.scene.spec",
    "SceneSpec": "sim.scene.spec",
    "SimSpec": "sim.scene.spec",
    "dump_scene": "sim.scene.spec",
    "load_scene": "sim.scene.spec",
    "parse_scene": "sim.scene.spec",
    "SceneError": "sim.scene.tomlio",
    "env_mask": "sim.scene.validate",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
