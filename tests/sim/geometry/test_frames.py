"""Frames: parallel transport, re-orthonormalisation, time-parallel update, reference twist (docs/physics.md §1.3)."""
from __future__ import annotations

import numpy as np

from sim.geometry.frames import (
    initial_reference_frames,
    reference_twist,
    rotate_about,
    transport,
    update_frames,
)


def _unit(v):
    return v / np.linalg.norm(v)


def test_transport_is_orthonormal_and_rotation():
    rng = np.random.default_rng(0)
    for _ in range(50):
        ta, tb = _unit(rng.standard_normal(3)), _unit(rng.standard_normal(3))
        u = _unit(np.cross(ta, rng.standard_normal(3)))
        v = np.array(transport(tuple(u), tuple(ta), tuple(tb)))
        assert abs(v @ tb) < 1e-14 and abs(np.linalg.norm(v) - 1) < 1e-14
        # the binormal component is preserved (rotation about ta × tb)
        b = _unit(np.cross(ta, tb))
        assert abs(v @ b - u @ b) < 1e-13
        # transport back returns u
        w = np.array(transport(tuple(v), tuple(tb), tuple(ta)))
        assert np.abs(w - u).max() < 1e-12


def test_transport_reorthonormalises_drifted_input():
    ta = np.array([0.0, 0.0, 1.0])
    tb = _unit(np.array([0.1, 0.0, 1.0]))
    u = np.array([1.0, 1e-4, 3e-4])   # slightly off-orthogonal and off-unit
    v = np.array(transport(tuple(u), tuple(ta), tuple(tb)))
    assert abs(v @ tb) < 1e-15 and abs(np.linalg.norm(v) - 1) < 1e-15
    # parallel tangents: unchanged up to re-orthonormalisation
    v2 = np.array(transport((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0)))
    assert np.array_equal(v2, [1.0, 0.0, 0.0])


def test_initial_frames_follow_reference_rule():
    # rod along +z: t×(0,0,-1) = 0 -> fallback t×(0,1,0) = (-1, 0, 0)
    x = np.array([[0, 0, 0], [0, 0, 0.5], [0, 0, 1.0]])
    d1, t = initial_reference_frames(x)
    assert np.allclose(d1[0], [-1, 0, 0]) and np.allclose(t[0], [0, 0, 1])
    # rod along +x: d1 = (0, 1, 0); inclined rod: d1 is normalised ([REC])
    d1, _ = initial_reference_frames(np.array([[0, 0, 0], [1.0, 0, 0]]))
    assert np.allclose(d1[0], [0, 1, 0])
    d1, _ = initial_reference_frames(np.array([[0, 0, 0], [1.0, 0, 1.0]]))
    assert abs(np.linalg.norm(d1[0]) - 1) < 1e-15


def test_time_parallel_update_and_reference_twist():
    rng = np.random.default_rng(1)
    N = 8
    x = np.cumsum(0.1 * _unit(np.array([1.0, 0.2, 0.1])) + 0.03 * rng.standard_normal((N, 3)), axis=0)
    d1o, to = initial_reference_frames(x)
    bo = np.zeros(N)
    t, d1, d2 = np.empty((N - 1, 3)), np.empty((N - 1, 3)), np.empty((N - 1, 3))
    elen, beta = np.empty(N - 1), np.empty(N)
    # unchanged positions: frames unchanged, β = 0 for space-parallel frames
    update_frames(x, d1o, to, bo, t, d1, d2, elen, beta)
    assert np.abs(d1 - d1o).max() < 1e-14 and np.abs(beta).max() < 1e-14
    # moved positions: orthonormal frames
    x2 = x + 0.02 * rng.standard_normal(x.shape)
    update_frames(x2, d1o, to, bo, t, d1, d2, elen, beta)
    assert np.abs(np.einsum("ij,ij->i", d1, t)).max() < 1e-14
    assert np.abs(np.linalg.norm(d1, axis=1) - 1).max() < 1e-14
    assert np.abs(np.linalg.norm(d2, axis=1) - 1).max() < 1e-14
    assert np.allclose(elen, np.linalg.norm(np.diff(x2, axis=0), axis=1))
    # rotating positions and step-start frames rigidly rotates the result; β stays 0 (frame invariance)
    ax = _unit(np.array([0.3, -1.0, 0.5]))

    def rot(v):
        return np.array(rotate_about(tuple(v), tuple(ax), 0.9))

    xr = np.array([rot(p) for p in x2])
    d1r, tr = np.array([rot(v) for v in d1o]), np.array([rot(v) for v in to])
    update_frames(x2, d1o, to, bo, t, d1, d2, elen, beta)
    beta_ref, d1_ref = beta.copy(), d1.copy()
    update_frames(xr, d1r, tr, bo, t, d1, d2, elen, beta)
    assert np.abs(beta - beta_ref).max() < 1e-12
    assert np.abs(d1 - np.array([rot(v) for v in d1_ref])).max() < 1e-12


def test_reference_twist_is_incremental_beyond_pi():
    """β accumulates without 2π wrapping when frames are rotated in small increments."""
    t = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    beta = 0.0
    for k in range(1, 41):
        ang = 0.1 * k
        d1 = np.array([[1.0, 0.0, 0.0], [np.cos(ang), np.sin(ang), 0.0]])
        beta = reference_twist(d1, t, 1, beta)
    assert abs(beta - 4.0) < 1e-12


def test_transport_antiparallel_and_near_antiparallel_stay_finite_unit():
    """A tangent that flips (1 + ta·tb -> 0) has no unique transport; the result must still be a finite unit
    vector ⟂ tb, never NaN."""
    ta = np.array([0.0, 0.0, 1.0])
    u = (1.0, 0.0, 0.0)
    for eps in (0.0, 1e-14, 1e-9, 1e-6):
        tb = _unit(np.array([eps, 0.3 * eps, -1.0]))
        v = np.array(transport(u, tuple(ta), tuple(tb)))
        assert np.all(np.isfinite(v)), eps
        assert abs(v @ tb) < 1e-12 and abs(np.linalg.norm(v) - 1) < 1e-12, eps
