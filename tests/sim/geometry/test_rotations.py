"""sim.geometry.rotations (the one quaternion module, wxyz) and sim.geometry.curvature: round trips and closed forms."""
from __future__ import annotations

import numpy as np

from sim.geometry.curvature import curvature_binormal, material_curvature
from sim.geometry.rotations import (
    from_xyzw,
    matrix_to_quat,
    quat_to_matrix,
    quat_yaw,
    quat_z_to,
    to_xyzw,
    yaw_quat,
)


def test_quaternion_matrix_round_trip_and_orthonormal():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    R = quat_to_matrix(q)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    q2 = matrix_to_quat(R)
    np.testing.assert_allclose(np.abs(np.sum(q * q2, axis=1)), 1.0, atol=1e-12)  # same rotation up to sign
    np.testing.assert_allclose(from_xyzw(to_xyzw(q)), q)


def test_shortest_rotation_and_yaw():
    d = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -0.6, 0.8], [0.0, 0.0, -1.0]])
    R = quat_to_matrix(quat_z_to(d))
    np.testing.assert_allclose(R[..., :, 2], d, atol=1e-12)
    yaw = np.array([-3.0, -0.5, 0.0, 1.2, 3.1])
    np.testing.assert_allclose(quat_yaw(yaw_quat(yaw)), yaw, atol=1e-12)


def test_curvature_of_a_regular_polygon():
    """Turning angle φ at every interior node: |κb| = 2 tan(φ/2), κ1 = |κb| for a planar arc with m2 = its
    binormal, κ2 = 0."""
    phi = 0.1
    a = np.arange(8) * phi
    pos = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    kb = curvature_binormal(pos)
    np.testing.assert_allclose(np.linalg.norm(kb[1:-1], axis=1), 2 * np.tan(phi / 2), rtol=1e-12)
    assert np.all(kb[[0, -1]] == 0.0)
    m2 = np.tile([0.0, 0.0, 1.0], (7, 1))
    t = np.diff(pos, axis=0)
    m1 = np.cross(m2, t / np.linalg.norm(t, axis=1, keepdims=True))
    k = material_curvature(pos, m1, m2)
    np.testing.assert_allclose(k[1:-1, 0], 2 * np.tan(phi / 2), rtol=1e-12)
    np.testing.assert_allclose(k[1:-1, 1], 0.0, atol=1e-15)
