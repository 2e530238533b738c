"""Rotations: the one conversion module. Quaternions are unit and scalar-first (w, x, y, z) everywhere in
rodlab; :func:`to_xyzw` / :func:`from_xyzw` reorder for the few outside formats that are scalar-last (task
observations follow SciPy's order, rerun takes x y z w). Pure numpy, vectorised over leading axes."""
from __future__ import annotations

import numpy as np

__all__ = ["quat_to_matrix", "matrix_to_quat", "quat_z_to", "yaw_quat", "quat_yaw", "to_xyzw", "from_xyzw"]


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) wxyz (normalised here) -> rotation matrices (..., 3, 3)."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) wxyz.

    SciPy's branch rule (``Rotation.from_matrix``: the largest of the three diagonal entries and the trace picks
    the pivot; the sign is not canonicalised), elementwise, so a result does not depend on the batch size.
    """
    R = np.asarray(R, np.float64)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    choice = np.argmax(np.stack([R[..., 0, 0], R[..., 1, 1], R[..., 2, 2], tr], axis=-1), axis=-1)
    q = np.empty(R.shape[:-2] + (4,))  # built scalar-last, reordered at the end
    t = choice == 3
    q[..., 0] = np.where(t, R[..., 2, 1] - R[..., 1, 2], 0.0)
    q[..., 1] = np.where(t, R[..., 0, 2] - R[..., 2, 0], 0.0)
    q[..., 2] = np.where(t, R[..., 1, 0] - R[..., 0, 1], 0.0)
    q[..., 3] = np.where(t, 1.0 + tr, 0.0)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        m = choice == i
        q[..., i] = np.where(m, 1.0 - tr + 2.0 * R[..., i, i], q[..., i])
        q[..., j] = np.where(m, R[..., j, i] + R[..., i, j], q[..., j])
        q[..., k] = np.where(m, R[..., k, i] + R[..., i, k], q[..., k])
        q[..., 3] = np.where(m, R[..., k, j] - R[..., j, k], q[..., 3])
    n = np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    return from_xyzw(q / np.where(n > 0, n, 1.0))


def quat_z_to(direction: np.ndarray) -> np.ndarray:
    """Shortest rotations taking +z onto each ``direction`` (..., 3) (normalised here) -> wxyz (..., 4);
    for ``direction`` = −z, a half turn about x."""
    d = np.asarray(direction, np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    w = 1.0 + d[..., 2]
    q = np.stack([w, -d[..., 1], d[..., 0], np.zeros_like(w)], -1)
    q[w < 1e-9] = np.array([0.0, 1.0, 0.0, 0.0])
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def yaw_quat(yaw: np.ndarray) -> np.ndarray:
    """Yaw angles (...,) [rad] about world z -> wxyz (..., 4) = (cos(y/2), 0, 0, sin(y/2))."""
    yaw = np.asarray(yaw, np.float64)
    q = np.zeros(yaw.shape + (4,))
    q[..., 0] = np.cos(0.5 * yaw)
    q[..., 3] = np.sin(0.5 * yaw)
    return q


def quat_yaw(q: np.ndarray) -> np.ndarray:
    """Yaw [rad] (the z-y-x Euler angle about world z) of quaternions (..., 4) wxyz."""
    q = np.asarray(q, np.float64)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def to_xyzw(q: np.ndarray) -> np.ndarray:
    """wxyz (..., 4) -> scalar-last xyzw (a new array)."""
    q = np.asarray(q)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def from_xyzw(q: np.ndarray) -> np.ndarray:
    """Scalar-last xyzw (..., 4) -> wxyz (a new array)."""
    q = np.asarray(q)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


def matrix_from_rotvec(rotvec) -> np.ndarray:
    """The rotation (3, 3) by the rotation vector ``rotvec`` [rad] (axis × angle; Rodrigues' formula)."""
    v = np.asarray(rotvec, np.float64)
    a = float(np.linalg.norm(v))
    if a == 0.0:
        return np.eye(3)
    k = v / a
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * (K @ K)
