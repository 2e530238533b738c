"""Contact (docs/physics.md §4): one protocol, two implementations.

- :mod:`sim.contact.stages`: the protocol the Newton stages call once per stage (broad phase, refresh,
  penetration, step limit, residual/Jacobian, energy, report) on a :class:`ContactSets`;
- :mod:`sim.contact.obstacles`: rod edges against rigid obstacles (planes, spheres, capsules, boxes, meshes);
- :mod:`sim.contact.edge_pairs`: rod edges against rod edges (self- and rod–rod contact);
- :mod:`sim.contact.imc`: the IMC potential and smooth Coulomb friction both use;
- :mod:`sim.contact.mesh`: mesh files and their bounding-volume trees.
"""
from __future__ import annotations

from .stages import ContactSets

__all__ = ["ContactSets"]
