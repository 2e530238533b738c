"""What the 3D view draws for one instant: :class:`Frame`, plus small geometry helpers.

A ``Frame`` is produced from the live simulator (``workbench.simbridge``) or from a recorded
episode (``workbench.replay``); the view renders both the same way, so the overlays match.
"""
from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass
class Frame:
    """One drawable instant of one rod.

    Attributes:
        node_pos: (N, 3) node positions [m].
        rod_radius: cross-section radius [m].
        m1, m2: (N-1, 3) material directors per edge (unit) or None when unknown.
        node_curvature: (N,) magnitude of the integrated curvature |κ| at nodes [-] (0 at the ends).
        edge_strain: (N-1,) axial strain |e_j|/l0_j - 1 [-], or None.
        contact_points: (K, 3) rod-side contact points [m].
        contact_forces: (K, 3) contact force on the rod [N] (normal + friction).
        contact_normals: (K, 3) unit normals (obstacle -> rod); contact_normal_force: (K,) [N].
        targets: (T, 3) target marker positions [m].
        time: simulated time [s].
        scalars: named live values (reward, reward terms, tip error, newton_iters, ...).
    """

    node_pos: np.ndarray
    rod_radius: float
    m1: np.ndarray | None = None
    m2: np.ndarray | None = None
    node_curvature: np.ndarray | None = None
    edge_strain: np.ndarray | None = None
    contact_points: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    contact_forces: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    contact_normals: np.ndarray | None = None
    contact_normal_force: np.ndarray | None = None
    targets: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    target_wxyz: np.ndarray | None = None
    time: float = 0.0
    scalars: dict[str, float] = dataclasses.field(default_factory=dict)

    @property
    def tip(self) -> np.ndarray:
        return self.node_pos[-1]


def integrated_curvature(node_pos: np.ndarray) -> np.ndarray:
    """|κb_i| = 2 tan(φ_i/2) at every node (ends 0). node_pos (..., N, 3) -> (..., N)."""
    e = np.diff(node_pos, axis=-2)
    t = e / np.maximum(np.linalg.norm(e, axis=-1, keepdims=True), 1e-12)
    a, b = t[..., :-1, :], t[..., 1:, :]
    kb = 2.0 * np.cross(a, b) / np.maximum(1.0 + np.sum(a * b, axis=-1), 1e-9)[..., None]
    out = np.zeros(node_pos.shape[:-1])
    out[..., 1:-1] = np.linalg.norm(kb, axis=-1)
    return out


def edge_strain(node_pos: np.ndarray, rest_length: np.ndarray) -> np.ndarray:
    """Axial strain per edge: (..., N, 3), (N-1,) -> (..., N-1)."""
    return np.linalg.norm(np.diff(node_pos, axis=-2), axis=-1) / rest_length - 1.0


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) in wxyz order."""
    R = np.asarray(R, dtype=np.float64)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    q = np.empty(R.shape[:-2] + (4,))
    c0 = tr > 0
    s = np.sqrt(np.maximum(tr + 1.0, 1e-12)) * 2
    q0 = np.stack([0.25 * s, (R[..., 2, 1] - R[..., 1, 2]) / s, (R[..., 0, 2] - R[..., 2, 0]) / s,
                   (R[..., 1, 0] - R[..., 0, 1]) / s], -1)
    s1 = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 1e-12)) * 2
    q1 = np.stack([(R[..., 2, 1] - R[..., 1, 2]) / s1, 0.25 * s1, (R[..., 0, 1] + R[..., 1, 0]) / s1,
                   (R[..., 0, 2] + R[..., 2, 0]) / s1], -1)
    s2 = np.sqrt(np.maximum(1.0 + m11 - m00 - m22, 1e-12)) * 2
    q2 = np.stack([(R[..., 0, 2] - R[..., 2, 0]) / s2, (R[..., 0, 1] + R[..., 1, 0]) / s2, 0.25 * s2,
                   (R[..., 1, 2] + R[..., 2, 1]) / s2], -1)
    s3 = np.sqrt(np.maximum(1.0 + m22 - m00 - m11, 1e-12)) * 2
    q3 = np.stack([(R[..., 1, 0] - R[..., 0, 1]) / s3, (R[..., 0, 2] + R[..., 2, 0]) / s3,
                   (R[..., 1, 2] + R[..., 2, 1]) / s3, 0.25 * s3], -1)
    c1 = ~c0 & (m00 > m11) & (m00 > m22)
    c2 = ~c0 & ~c1 & (m11 > m22)
    q[...] = q3
    q[c2] = q2[c2]
    q[c1] = q1[c1]
    q[c0] = q0[c0]
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_z_to(direction: np.ndarray) -> np.ndarray:
    """Shortest rotations taking +z to each unit ``direction`` (..., 3) -> wxyz (..., 4)."""
    d = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-12)
    w = 1.0 + d[..., 2]
    q = np.stack([w, -d[..., 1], d[..., 0], np.zeros_like(w)], -1)
    flip = w < 1e-9  # d == -z: rotate pi about x
    q[flip] = np.array([0.0, 1.0, 0.0, 0.0])
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def colormap(values: np.ndarray, vmax: float) -> np.ndarray:
    """Map values in [0, vmax] to a blue→green→red ramp; returns (..., 3) uint8."""
    s = np.clip(np.asarray(values, dtype=np.float64) / max(vmax, 1e-12), 0.0, 1.0)
    r = np.clip(2.0 * s - 0.5, 0.0, 1.0)
    g = np.clip(1.5 - np.abs(4.0 * s - 2.0), 0.0, 1.0) * 0.85 + 0.1
    b = np.clip(1.5 - 2.0 * s, 0.0, 1.0)
    return (np.stack([r, g, b], -1) * 255).astype(np.uint8)
