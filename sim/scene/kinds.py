"""Obstacle kind codes: the one definition, read by the scene specs (:mod:`sim.scene.obstacles`), the runtime arrays
(:mod:`sim.contact.world`) and the numba contact kernels (:mod:`sim.contact.obstacles`, as compile-time constants)."""
from __future__ import annotations

__all__ = ["PLANE", "SPHERE", "CAPSULE", "BOX", "MESH", "KIND_CODES"]

PLANE = 0
SPHERE = 1
CAPSULE = 2
BOX = 3
MESH = 4
# a flat-ended cylinder is contacted as a mesh (a closed 48-sided prism, sim/contact/mesh.py)
KIND_CODES = {"plane": PLANE, "sphere": SPHERE, "capsule": CAPSULE, "box": BOX, "mesh": MESH, "cylinder": MESH}
