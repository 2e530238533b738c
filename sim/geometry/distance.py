"""Exact closest points between a rod edge (segment) and rigid features, and the derivatives of the distance.

All functions are numba ``njit`` kernels. 3-vectors are passed as float tuples ``(x, y, z)`` [m] so the
hot paths allocate nothing; ``ws`` is a caller-owned float64 scratch array (>= 64 entries).

Closest-point queries return the segment parameter ``s`` in [0, 1] (rod point ``a + s (b - a)``), the
obstacle point ``q`` and the obstacle's *free* directions at the solution (0, 1 or 2 vectors ``d``: the
obstacle point moves as ``q + w1 d1 + w2 d2`` inside the active feature: face -> 2, edge -> 1, vertex -> 0).

:func:`dist_derivs` turns that classification into the distance ``Delta`` and its exact gradient (6,)
and Hessian (6, 6) with respect to the two rod nodes ``(a, b)``, by the Schur complement of docs/physics.md
§4.2: with ``h(x, y) = |u|^2 / 2``, ``u = a + s (b - a) - q(w)`` and ``y`` the interior parameters
(``s`` if 0 < s < 1, and the obstacle's free ``w``), ``hess h* = h_xx - h_xy h_yy^-1 h_yx``; then
``grad Delta = J^T n``, ``hess Delta = (hess h* - grad Delta grad Delta^T) / Delta``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.geometry.vec3 import vadd, vcross, vdot, vlerp, vmul, vsub
from sim.numba_options import OPT_CONTACT

__all__ = ["closest_seg_point", "closest_seg_seg", "closest_point_triangle", "closest_seg_triangle",
           "closest_seg_box", "dist_derivs"]

_EPS_PARAM = 1e-12


@njit(**OPT_CONTACT)
def closest_seg_point(a, b, c):
    """Segment (a, b) vs point c: return s in [0, 1] of the closest rod point."""
    e = vsub(b, a)
    ee = vdot(e, e)
    if ee <= 0.0:
        return 0.0
    s = vdot(vsub(c, a), e) / ee
    return min(1.0, max(0.0, s))


@njit(**OPT_CONTACT)
def closest_seg_seg(a, b, p, q):
    """Segments (a, b) and (p, q), Lumelsky's rule (docs/physics.md §4.2): return (s, u) in [0, 1]^2.

    Exactly parallel pairs (den = 0) get s = 0 first, i.e. they are classified point-edge.
    """
    e1 = vsub(b, a)
    e2 = vsub(q, p)
    e12 = vsub(p, a)
    d1 = vdot(e1, e1)
    d2 = vdot(e2, e2)
    r = vdot(e1, e2)
    s1 = vdot(e1, e12)
    s2 = vdot(e2, e12)
    den = d1 * d2 - r * r
    if d1 <= 0.0 and d2 <= 0.0:
        return 0.0, 0.0
    if d1 <= 0.0:
        return 0.0, min(1.0, max(0.0, -s2 / d2))
    if d2 <= 0.0:
        return min(1.0, max(0.0, s1 / d1)), 0.0
    t = 0.0
    if den > 1e-14 * d1 * d2:
        t = (s1 * d2 - s2 * r) / den
        t = min(1.0, max(0.0, t))
    u = (t * r - s2) / d2
    if u < 0.0 or u > 1.0:
        u = min(1.0, max(0.0, u))
        t = (u * r + s1) / d1
        t = min(1.0, max(0.0, t))
    return t, u


@njit(**OPT_CONTACT)
def closest_point_triangle(p, v0, v1, v2):
    """Closest point of triangle (v0, v1, v2) to point p (Voronoi-region walk).

    Returns ``(nfree, q, d1, d2)``: free directions 2 (face), 1 (edge), 0 (vertex).
    """
    z = (0.0, 0.0, 0.0)
    ab = vsub(v1, v0)
    ac = vsub(v2, v0)
    ap = vsub(p, v0)
    da1 = vdot(ab, ap)
    da2 = vdot(ac, ap)
    if da1 <= 0.0 and da2 <= 0.0:
        return 0, v0, z, z
    bp = vsub(p, v1)
    d3 = vdot(ab, bp)
    d4 = vdot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return 0, v1, z, z
    vc = da1 * d4 - d3 * da2
    if vc <= 0.0 and da1 >= 0.0 and d3 <= 0.0:
        w = da1 / (da1 - d3)
        return 1, vadd(v0, vmul(w, ab)), ab, z
    cp = vsub(p, v2)
    d5 = vdot(ab, cp)
    d6 = vdot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return 0, v2, z, z
    vb = d5 * da2 - da1 * d6
    if vb <= 0.0 and da2 >= 0.0 and d6 <= 0.0:
        w = da2 / (da2 - d6)
        return 1, vadd(v0, vmul(w, ac)), ac, z
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        bc = vsub(v2, v1)
        return 1, vadd(v1, vmul(w, bc)), bc, z
    den = 1.0 / (va + vb + vc)
    v = vb * den
    w = vc * den
    return 2, vadd(v0, vadd(vmul(v, ab), vmul(w, ac))), ab, ac


@njit(**OPT_CONTACT)
def closest_seg_triangle(a, b, v0, v1, v2):
    """Segment (a, b) vs triangle: unsigned distance.

    Returns ``(dist, s, nfree, q, d1, d2, nrm)``. ``nrm`` is zero unless the segment pierces the triangle
    (dist = 0): then it is the triangle normal on the side holding the longer part of the segment.
    """
    z = (0.0, 0.0, 0.0)
    n = vcross(vsub(v1, v0), vsub(v2, v0))
    nn = math.sqrt(vdot(n, n))
    if nn > 0.0:
        n = vmul(1.0 / nn, n)
        ha = vdot(n, vsub(a, v0))
        hb = vdot(n, vsub(b, v0))
        if (ha < 0.0 < hb) or (hb < 0.0 < ha):
            s = ha / (ha - hb)
            x = vlerp(a, b, s)
            c0 = vdot(vcross(vsub(v1, v0), vsub(x, v0)), n)
            c1 = vdot(vcross(vsub(v2, v1), vsub(x, v1)), n)
            c2 = vdot(vcross(vsub(v0, v2), vsub(x, v2)), n)
            if c0 >= 0.0 and c1 >= 0.0 and c2 >= 0.0:
                sg = 1.0 if ((ha > 0.0 and s >= 0.5) or (hb > 0.0 and s < 0.5)) else -1.0
                return 0.0, s, 0, x, z, z, vmul(sg, n)
    # endpoints vs the triangle
    nf, q, d1, d2 = closest_point_triangle(a, v0, v1, v2)
    best = vdot(vsub(a, q), vsub(a, q))
    best_s = 0.0
    nf2, q2, e1, e2 = closest_point_triangle(b, v0, v1, v2)
    dd = vdot(vsub(b, q2), vsub(b, q2))
    if dd < best:
        best = dd
        best_s = 1.0
        nf = nf2
        q = q2
        d1 = e1
        d2 = e2
    # segment vs the three triangle edges
    for k in range(3):
        if k == 0:
            p0 = v0
            p1 = v1
        elif k == 1:
            p0 = v1
            p1 = v2
        else:
            p0 = v2
            p1 = v0
        s, u = closest_seg_seg(a, b, p0, p1)
        x = vlerp(a, b, s)
        y = vlerp(p0, p1, u)
        dd = vdot(vsub(x, y), vsub(x, y))
        if dd < best:
            best = dd
            best_s = s
            q = y
            d2 = z
            if u > _EPS_PARAM and u < 1.0 - _EPS_PARAM:
                nf = 1
                d1 = vsub(p1, p0)
            else:
                nf = 0
                d1 = z
    return math.sqrt(best), best_s, nf, q, d1, d2, z


@njit(**OPT_CONTACT)
def closest_seg_box(a, b, h, ws):
    """Segment (a, b) vs the solid box |x_i| <= h_i, all in the box's local frame.

    Returns ``(signed_dist, s, free_mask, q, nrm)``. Outside: the exact Euclidean distance (convex
    piecewise-quadratic minimisation over s), ``q`` the closest box point, ``free_mask`` bit i set when
    local axis i is a free direction of the box feature, ``nrm`` zero. Inside (the centre line enters the
    box): the most negative ``max_i(|x_i| - h_i)`` along the segment, ``q`` its projection onto the nearest
    face, ``nrm`` that face's outward normal and ``free_mask = -1``.
    """
    e = vsub(b, a)
    br = ws[:8]
    nb = 0
    br[nb] = 0.0
    nb += 1
    br[nb] = 1.0
    nb += 1
    for i in range(3):
        if e[i] != 0.0:
            for sg in (-1.0, 1.0):
                t = (sg * h[i] - a[i]) / e[i]
                if 0.0 < t < 1.0:
                    br[nb] = t
                    nb += 1
    for i in range(1, nb):  # insertion sort (<= 8 values)
        key = br[i]
        j = i - 1
        while j >= 0 and br[j] > key:
            br[j + 1] = br[j]
            j -= 1
        br[j + 1] = key
    best = np.inf
    best_s = 0.0
    for k in range(nb - 1):
        s0 = br[k]
        s1 = br[k + 1]
        if s1 <= s0:
            continue
        m = 0.5 * (s0 + s1)
        A = 0.0
        B = 0.0
        C = 0.0
        for i in range(3):
            xm = a[i] + m * e[i]
            if xm > h[i]:
                al = a[i] - h[i]
            elif xm < -h[i]:
                al = a[i] + h[i]
            else:
                continue
            A += al * e[i]
            B += e[i] * e[i]
            C += al * al
        s = s0
        if B > 0.0:
            s = min(s1, max(s0, -A / B))
        val = C + 2.0 * A * s + B * s * s
        if val < best:
            best = val
            best_s = s
    x = vlerp(a, b, best_s)
    mask = 0
    q0 = min(h[0], max(-h[0], x[0]))
    q1 = min(h[1], max(-h[1], x[1]))
    q2 = min(h[2], max(-h[2], x[2]))
    if abs(x[0]) <= h[0]:
        mask |= 1
    if abs(x[1]) <= h[1]:
        mask |= 2
    if abs(x[2]) <= h[2]:
        mask |= 4
    dsq = (x[0] - q0) ** 2 + (x[1] - q1) ** 2 + (x[2] - q2) ** 2
    if mask != 7 and dsq > 1e-24:
        return math.sqrt(dsq), best_s, mask, (q0, q1, q2), (0.0, 0.0, 0.0)
    # penetration: minimise the max of six linear functions of s (a 1-D LP over candidate points)
    best = np.inf
    best_s = 0.0
    for j1 in range(-1, 6):
        for j2 in range(j1 + 1, 6):
            if j1 < 0:
                s = 0.0 if j2 == 0 else (1.0 if j2 == 1 else -1.0)
                if s < 0.0:
                    continue
            else:
                i1 = j1 // 2
                g1 = 1.0 if j1 % 2 == 0 else -1.0
                i2 = j2 // 2
                g2 = 1.0 if j2 % 2 == 0 else -1.0
                den = g1 * e[i1] - g2 * e[i2]
                if den == 0.0:
                    continue
                s = -((g1 * a[i1] - h[i1]) - (g2 * a[i2] - h[i2])) / den
                if not (0.0 < s < 1.0):
                    continue
            f = max(abs(a[0] + s * e[0]) - h[0], abs(a[1] + s * e[1]) - h[1], abs(a[2] + s * e[2]) - h[2])
            if f < best:
                best = f
                best_s = s
    x = vlerp(a, b, best_s)
    f0 = abs(x[0]) - h[0]
    f1 = abs(x[1]) - h[1]
    f2 = abs(x[2]) - h[2]
    if f0 >= f1 and f0 >= f2:
        sg = 1.0 if x[0] >= 0.0 else -1.0
        return f0, best_s, -1, (sg * h[0], x[1], x[2]), (sg, 0.0, 0.0)
    if f1 >= f2:
        sg = 1.0 if x[1] >= 0.0 else -1.0
        return f1, best_s, -1, (x[0], sg * h[1], x[2]), (0.0, sg, 0.0)
    sg = 1.0 if x[2] >= 0.0 else -1.0
    return f2, best_s, -1, (x[0], x[1], sg * h[2]), (0.0, 0.0, sg)


@njit(**OPT_CONTACT)
def dist_derivs(a, b, s, q, nfree, d1, d2, fallback_n, grad, hess, nhat, ws):
    """Distance between rod point ``a + s (b - a)`` and obstacle point ``q``, with derivatives.

    ``nfree`` obstacle free directions ``d1``, ``d2`` (see module doc); ``s`` counts as free when strictly
    inside (0, 1). Writes ``grad`` (6,) = dDelta/d(a, b), ``hess`` (6, 6) and the unit normal ``nhat`` (3,)
    (obstacle -> rod). If the distance is ~0 the normal is ``fallback_n`` (or a unit vector orthogonal
    to the edge) and the Hessian is 0 (Gauss-Newton). Returns Delta [m].
    """
    w0 = 1.0 - s
    w1 = s
    u = vsub(vlerp(a, b, s), q)
    dd = math.sqrt(vdot(u, u))
    e = vsub(b, a)
    el = math.sqrt(vdot(e, e))
    if dd <= 1e-12 * max(el, 1.0):
        fn = math.sqrt(vdot(fallback_n, fallback_n))
        if fn > 0.0:
            n = vmul(1.0 / fn, fallback_n)
        else:
            ax = 0
            if abs(e[1]) < abs(e[ax]):
                ax = 1
            if abs(e[2]) < abs(e[ax]):
                ax = 2
            tmp = (1.0 if ax == 0 else 0.0, 1.0 if ax == 1 else 0.0, 1.0 if ax == 2 else 0.0)
            c = vcross(e, tmp)
            cn = math.sqrt(vdot(c, c))
            n = vmul(1.0 / cn, c) if cn > 0.0 else (0.0, 0.0, 1.0)
        for i in range(3):
            nhat[i] = n[i]
            grad[i] = w0 * n[i]
            grad[3 + i] = w1 * n[i]
        hess[:, :] = 0.0
        return 0.0
    inv = 1.0 / dd
    for i in range(3):
        nhat[i] = u[i] * inv
        grad[i] = w0 * nhat[i]
        grad[3 + i] = w1 * nhat[i]
    hess[:, :] = 0.0
    for i in range(3):  # h_xx = J^T J
        hess[i, i] = w0 * w0
        hess[i, 3 + i] = w0 * w1
        hess[3 + i, i] = w0 * w1
        hess[3 + i, 3 + i] = w1 * w1
    # interior parameters: G (3 x m) at ws[0:9] (column-major), h_xy (6 x m) at ws[9:27] (M[r, j] = ws[9+6j+r])
    m = 0
    if s > _EPS_PARAM and s < 1.0 - _EPS_PARAM:
        for i in range(3):
            ws[i] = e[i]
            ws[9 + i] = w0 * e[i] - u[i]
            ws[12 + i] = w1 * e[i] + u[i]
        m = 1
    for kk in range(nfree):
        d = d1 if kk == 0 else d2
        for i in range(3):
            ws[3 * m + i] = -d[i]
            ws[9 + 6 * m + i] = -w0 * d[i]
            ws[12 + 6 * m + i] = -w1 * d[i]
        m += 1
    if m > 0:
        # Cholesky of h_yy = G^T G (ws[27:36] A, ws[36:45] L), tiny pivots skipped
        tr = 0.0
        for i in range(m):
            for j in range(m):
                ws[27 + 3 * i + j] = (ws[3 * i] * ws[3 * j] + ws[3 * i + 1] * ws[3 * j + 1]
                                      + ws[3 * i + 2] * ws[3 * j + 2])
            tr += ws[27 + 4 * i]
        for i in range(9):
            ws[36 + i] = 0.0
        for j in range(m):
            v = ws[27 + 4 * j]
            for k in range(j):
                v -= ws[36 + 3 * j + k] ** 2
            if v > 1e-13 * tr:
                ljj = math.sqrt(v)
                ws[36 + 4 * j] = ljj
                for i in range(j + 1, m):
                    w = ws[27 + 3 * i + j]
                    for k in range(j):
                        w -= ws[36 + 3 * i + k] * ws[36 + 3 * j + k]
                    ws[36 + 3 * i + j] = w / ljj
        # Z = M L^-T row by row (in place), then hess -= Z Z^T
        for r in range(6):
            for j in range(m):
                ljj = ws[36 + 4 * j]
                if ljj == 0.0:
                    ws[9 + 6 * j + r] = 0.0
                    continue
                v = ws[9 + 6 * j + r]
                for k in range(j):
                    v -= ws[9 + 6 * k + r] * ws[36 + 3 * j + k]
                ws[9 + 6 * j + r] = v / ljj
        for r in range(6):
            for c in range(r, 6):
                acc = 0.0
                for j in range(m):
                    acc += ws[9 + 6 * j + r] * ws[9 + 6 * j + c]
                hess[r, c] -= acc
                if c != r:
                    hess[c, r] -= acc
    for r in range(6):
        for c in range(6):
            hess[r, c] = (hess[r, c] - grad[r] * grad[c]) * inv
    return dd
