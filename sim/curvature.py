"""Integrated curvature of a discrete rod (docs/physics.md §1.4), in numpy: the one place the binormal formula
lives outside the numba energies. κb_i = 2 t_{i−1} × t_i / (1 + t_{i−1}·t_i) at interior nodes,
κ1_i = ½ κb_i·(m2_{i−1} + m2_i), κ2_i = −½ κb_i·(m1_{i−1} + m1_i); rows 0 and N−1 are 0."""
from __future__ import annotations

import numpy as np

__all__ = ["curvature_binormal", "material_curvature"]


def curvature_binormal(pos: np.ndarray) -> np.ndarray:
    """Curvature binormals κb (..., N, 3) [-] of node positions ``pos`` (..., N, 3) [m] (rows 0, N−1 zero);
    |κb| = 2 tan(φ/2) with φ the turning angle."""
    pos = np.asarray(pos, np.float64)
    e = np.diff(pos, axis=-2)
    t = e / np.maximum(np.linalg.norm(e, axis=-1, keepdims=True), 1e-300)
    ta, tb = t[..., :-1, :], t[..., 1:, :]
    out = np.zeros(pos.shape)
    out[..., 1:-1, :] = 2.0 * np.cross(ta, tb) / np.maximum(1.0 + np.sum(ta * tb, axis=-1, keepdims=True), 1e-12)
    return out


def material_curvature(pos: np.ndarray, m1: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """Integrated material curvature (κ1, κ2) (..., N, 2) [-] of ``pos`` (..., N, 3) with material directors
    ``m1``, ``m2`` (..., N−1, 3) (rows 0, N−1 zero)."""
    kb = curvature_binormal(pos)[..., 1:-1, :]
    out = np.zeros(np.shape(pos)[:-1] + (2,))
    out[..., 1:-1, 0] = 0.5 * np.sum(kb * (m2[..., :-1, :] + m2[..., 1:, :]), axis=-1)
    out[..., 1:-1, 1] = -0.5 * np.sum(kb * (m1[..., :-1, :] + m1[..., 1:, :]), axis=-1)
    return out
