"""Integrated curvature of a discrete rod (docs/physics.md §1.4), in numpy: the one place the binormal formula
lives outside the numba energies. κb_i = 2 t_{i−1} × t_i / (1 + t_{i−1}·t_i) at interior nodes,
κ1_i = ½ κb_i·(m2_{i−1} + m2_i), κ2_i = −½ κb_i·(m1_{i−1} + m1_i); rows 0 and N−1 are 0."""
from __future__ import annotations

import numpy as np

__all__ = ["curvature_binormal", "material_curvature", "integrated_twist"]


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


def integrated_twist(pos: np.ndarray, m1: np.ndarray) -> np.ndarray:
    """Integrated twist τ (..., N) [rad] at the nodes of ``pos`` (..., N, 3) with first material directors ``m1``
    (..., N−1, 3): the signed angle about t_i from m1_{i−1}, parallel-transported onto edge i, to m1_i; it equals
    θ^i − θ^{i−1} + β_i of docs/physics.md §1.4 (modulo 2π). Rows 0 and N−1 are 0."""
    pos = np.asarray(pos, np.float64)
    m1 = np.asarray(m1, np.float64)
    e = np.diff(pos, axis=-2)
    t = e / np.maximum(np.linalg.norm(e, axis=-1, keepdims=True), 1e-300)
    ta, tb, ma, mb = t[..., :-1, :], t[..., 1:, :], m1[..., :-1, :], m1[..., 1:, :]
    c = np.cross(ta, tb)
    cos = np.sum(ta * tb, axis=-1, keepdims=True)
    # Rodrigues' rotation taking ta onto tb, applied to ma
    mt = ma * cos + np.cross(c, ma) + c * np.sum(c * ma, axis=-1, keepdims=True) / np.maximum(1.0 + cos, 1e-12)
    out = np.zeros(pos.shape[:-1])
    out[..., 1:-1] = np.arctan2(np.sum(np.cross(mt, mb) * tb, axis=-1), np.sum(mt * mb, axis=-1))
    return out
