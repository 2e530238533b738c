"""Contact (docs/physics.md §4): one protocol, two implementations.

- :mod:`sim.contact.stages`: the protocol the Newton stages call once per stage (broad phase, refresh,
  penetration, step limit, residual/Jacobian, energy, report) on a :class:`ContactSets`;
- :mod:`sim.contact.obstacles`: rod edges against rigid obstacles (planes, spheres, capsules, boxes, meshes);
- :mod:`sim.contact.edge_pairs`: rod edges against rod edges (self- and rod–rod contact);
- :mod:`sim.contact.imc`: the IMC potential and smooth Coulomb friction both use;
- :mod:`sim.contact.mesh`: mesh files and their bounding-volume trees;
- :mod:`sim.contact.world`: the obstacles at run time (geometry from the Model, poses from the State) as the arrays
  the kernels read.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {"ContactSets": "sim.contact.stages", "imc_energy": "sim.contact.imc",
         "load_mesh_triangles": "sim.contact.mesh", "OBSTACLE_ARRAYS": "sim.contact.world",
         "node_radii": "sim.contact.world"}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
