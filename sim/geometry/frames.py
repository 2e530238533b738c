"""Frames of the discrete rod (docs/physics.md §1.3): parallel transport, reference/material frames, reference twist.

Small vectors are passed as 3-tuples of floats (stack values inside numba). Array functions work on one
environment: ``x`` node positions (N, 3) [m], per-edge arrays (N-1, 3), per-node arrays (N,).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.geometry.vec3 import vaxpy, vcross, vdot, vmul, vnorm
from sim.numba_options import OPT

__all__ = ["transport", "transport_vectors", "rotate_about", "signed_angle", "initial_reference_frames",
           "update_frames", "reference_twist"]

_TWO_PI = 2.0 * math.pi


@njit(**OPT)
def transport(u, ta, tb):
    """Parallel transport P(u; ta -> tb) of a vector u ⟂ ta, then re-orthonormalised against tb (unit tb).

    The rotation about ta × tb taking ta to tb, in Rodrigues form with the unnormalised axis k = ta × tb and
    c = ta·tb: P u = c u + k × u + (k·u)/(1 + c) k (no square root; the same rotation as normalising the axis).
    Parallel tangents give u; (anti)parallel ones (1 + c ≤ 1e-12) have no unique rotation and also keep u.
    """
    c = vdot(ta, tb)
    if 1.0 + c > 1e-12:
        k = vcross(ta, tb)
        kxu = vcross(k, u)
        s = vdot(k, u) / (1.0 + c)
        out = (c * u[0] + kxu[0] + s * k[0], c * u[1] + kxu[1] + s * k[1], c * u[2] + kxu[2] + s * k[2])
    else:
        out = u
    out = vaxpy(-vdot(out, tb), tb, out)
    return vmul(1.0 / vnorm(out), out)


def transport_vectors(u, ta, tb) -> tuple:
    """:func:`transport` of three 3-vectors given as arrays (outside the kernels)."""
    return transport(tuple(map(float, u)), tuple(map(float, ta)), tuple(map(float, tb)))


@njit(**OPT)
def rotate_about(u, t, ang):
    """Rodrigues rotation of u about the unit axis t by ang [rad]."""
    c = math.cos(ang)
    s = math.sin(ang)
    txu = vcross(t, u)
    tu = vdot(t, u)
    return (u[0] * c + txu[0] * s + t[0] * tu * (1.0 - c),
            u[1] * c + txu[1] * s + t[1] * tu * (1.0 - c),
            u[2] * c + txu[2] * s + t[2] * tu * (1.0 - c))


@njit(**OPT)
def signed_angle(a, b, n):
    """Angle from a to b [rad], signed by the axis n."""
    c = vcross(a, b)
    ang = math.atan2(vnorm(c), vdot(a, b))
    if vdot(n, c) < 0.0:
        ang = -ang
    return ang


@njit(**OPT)
def update_frames(x, d1_old, t_old, beta_old, t, d1, d2, elen, beta, link=None):
    """Time-parallel frames at positions x (N, 3) from the step-start frames.

    Writes unit tangents ``t``, reference directors ``d1``, ``d2`` (N-1, 3), edge lengths ``elen`` (N-1,)
    and reference twists ``beta`` (N,) (0 at both end nodes). Returns the minimum edge length.

    ``link`` (N-1,) (optional; 1 a material edge, 0 a joint edge between two rods, docs/physics.md §1.7): a joint
    edge keeps its step-start frame (it may have zero length where two rods touch end to end), is left out of the
    minimum, and the nodes next to it get β = 0 (rod end nodes: no bending or twisting there).
    """
    ne = x.shape[0] - 1
    lmin = np.inf
    for j in range(ne):
        e = (x[j + 1, 0] - x[j, 0], x[j + 1, 1] - x[j, 1], x[j + 1, 2] - x[j, 2])
        le = vnorm(e)
        elen[j] = le
        if link is not None:
            if link[j] == 0:
                to = (t_old[j, 0], t_old[j, 1], t_old[j, 2])
                u = (d1_old[j, 0], d1_old[j, 1], d1_old[j, 2])
                v = vcross(to, u)
                for a in range(3):
                    t[j, a] = to[a]
                    d1[j, a] = u[a]
                    d2[j, a] = v[a]
                continue
        lmin = min(lmin, le)
        tj = vmul(1.0 / le, e)
        to = (t_old[j, 0], t_old[j, 1], t_old[j, 2])
        u = transport((d1_old[j, 0], d1_old[j, 1], d1_old[j, 2]), to, tj)
        v = vcross(tj, u)
        for a in range(3):
            t[j, a] = tj[a]
            d1[j, a] = u[a]
            d2[j, a] = v[a]
    beta[0] = 0.0
    beta[ne] = 0.0
    for i in range(1, ne):
        if link is not None:
            if link[i - 1] == 0 or link[i] == 0:
                beta[i] = 0.0
                continue
        beta[i] = reference_twist(d1, t, i, beta_old[i])
    return lmin


@njit(**OPT)
def reference_twist(d1, t, i, beta_old_i):
    """Reference twist β_i [rad] at interior node i, computed incrementally from β_old (§1.3).

    §1.3 rotates the transported d1_{i−1} by β_old about t_i and adds the signed angle from it to d1_i. That
    angle is the signed angle α from the transported d1_{i−1} to d1_i minus β_old, wrapped to [−π, π); this
    computes it that way (the same value, without the rotation's cos/sin), so β keeps counting whole turns.
    """
    ta = (t[i - 1, 0], t[i - 1, 1], t[i - 1, 2])
    tb = (t[i, 0], t[i, 1], t[i, 2])
    u = transport((d1[i - 1, 0], d1[i - 1, 1], d1[i - 1, 2]), ta, tb)
    # signed angle from u to d1_i about t_i: both are ⟂ t_i, so u × d1_i ∥ t_i and its t_i component is ±|u × d1_i|
    d1i = (d1[i, 0], d1[i, 1], d1[i, 2])
    dlt = math.atan2(vdot(tb, vcross(u, d1i)), vdot(u, d1i)) - beta_old_i
    dlt -= _TWO_PI * math.floor((dlt + math.pi) / _TWO_PI)
    return beta_old_i + dlt


def initial_reference_frames(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Space-parallel reference frames of a polyline x (N, 3): returns (d1, t), each (N-1, 3).

    First edge: d1 = t × (0,0,-1), or t × (0,1,0) if that is shorter than 1e-6; normalised ([REC]).
    """
    x = np.asarray(x, dtype=np.float64)
    e = np.diff(x, axis=0)
    t = e / np.linalg.norm(e, axis=1, keepdims=True)
    d1 = np.empty_like(t)
    c = np.cross(t[0], np.array([0.0, 0.0, -1.0]))
    if np.linalg.norm(c) < 1e-6:
        c = np.cross(t[0], np.array([0.0, 1.0, 0.0]))
    d1[0] = c / np.linalg.norm(c)
    for j in range(1, len(t)):
        d1[j] = transport(tuple(d1[j - 1]), tuple(t[j - 1]), tuple(t[j]))
    return d1, t
