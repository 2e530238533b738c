"""Geometry of the discrete rod shared by the kernels and the tools around them: rotations and quaternions (scalar
first, wxyz), the rod's reference and material frames, integrated curvature and twist, the exact distances between
an edge and the obstacles' features, and the 3-vector helpers of the numba kernels.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {
    "curvature_binormal": "sim.geometry.curvature",
    "integrated_twist": "sim.geometry.curvature",
    "material_curvature": "sim.geometry.curvature",
    "from_xyzw": "sim.geometry.rotations",
    "matrix_from_rotvec": "sim.geometry.rotations",
    "matrix_to_quat": "sim.geometry.rotations",
    "quat_to_matrix": "sim.geometry.rotations",
    "quat_yaw": "sim.geometry.rotations",
    "quat_z_to": "sim.geometry.rotations",
    "to_xyzw": "sim.geometry.rotations",
    "transport_vectors": "sim.geometry.frames",
    "yaw_quat": "sim.geometry.rotations",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
