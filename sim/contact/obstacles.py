"""IMC contact and friction kernels (numba), called per env from the step kernels in ``sim.kernels``
(docs/physics.md §4).

Model: every rod edge is a capsule of the rod radius ``r``. For each (edge, obstacle) candidate the
gap is ``g = Delta - r - R`` (``Delta`` the exact centre-line distance, ``R`` the obstacle radius for
spheres/capsules, 0 for boxes and meshes); planes act per node with ``g = n.(x_k - p) - r``. Energy
``E(g) = k softplus(-K1 g)^2 / K1^2`` (K1 = 15/delta, one stable formula); gradient ``E' grad Delta``,
Hessian ``E'' grad Delta grad Delta^T + E' hess Delta`` over the edge's two nodes (6 DOFs).

Flat faces: an edge whose two nodes both lie over the same face of a box, or over one flat region of a mesh
(both nodes' closest mesh points inside triangles, seen along the same direction and in one plane: one face,
or coplanar triangles), acts per node like a plane (weights 1/2 at nodes shared
by two edges, 1 at the rod's ends) instead of through its closest point, which jumps between the edge's ends as
a rod lying on the face tilts.

Ownership (docs/physics.md §4.7 artefact 1): a pair whose closest rod point is the edge's end node is left
to the next edge; a pair at the start node is skipped when the previous edge of the same obstacle is
strictly closer. So each local minimum of the distance along the rod is counted once.

Friction (§4.6): smooth Coulomb with lagged ``n`` and ``s`` (no derivatives through them), at every Newton
iterate, the first one included, as for edge pairs; skipped when ``friction_on`` is False.

``cd`` is the :class:`sim.contact.world.ContactData` namedtuple (:func:`sim.contact.world.contact_data`):
``(kind (M,), p0 (B,M,3), p1 (B,M,3), rot (B,M,3,3), obstacle_radius (B,M), half (M,3), mesh_root (M,),
tri (T,3,3), node_lo (K,3), node_hi (K,3), node_child (K,2), node_range (K,2), cand (B,C,2) int64,
cand_count (B,), broadphase_radius (1,) [m] (the rod's largest radius: the broad phase's inflation), active (B,M)
bool, box (B,M,2,3) world AABBs, scratch_f (B,128), scratch_m (B,2,6,6), scratch_i (B,128) int64 per-env work space (no
allocation in the kernels), friction (M,) per-obstacle μ (-1: the contact law's μ, the [contact] friction),
cand_merge (B,2C,2) int64 (the candidate lists merged by :func:`merge_candidates`))``.
Kinds: 0 plane (p0 point, p1 unit normal), 1 sphere (p0 centre), 2 capsule (p0, p1 axis ends),
3 box (p0 centre, rot, half), 4 mesh (p0, rot, mesh_root = BVH root node).
``radius``: the rod's edge radii (:mod:`sim.contact.imc`). ``law``: the contact law's parameters, a
:class:`sim.kernels.data.Params` record (contact_k, contact_delta, friction, friction_nu).
Shapes: ``x``, ``x_prev``, ``x_start``, ``x_end`` (N, >=3) [m]; ``grad`` (N, 3); ``hess`` (N-1, 6, 6)
(edge j's block over (x_j, x_{j+1}); row = residual component, may be non-symmetric).

The end of the module is the contact protocol (:mod:`sim.contact.stages`) for obstacles: the same functions, with
the same arguments, as :mod:`sim.contact.edge_pairs`, on an :class:`ObstacleContact`.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from sim.contact.imc import edge_radius, friction_block, imc_energy, node_radius, row3
from sim.geometry.distance import (
    closest_seg_box,
    closest_seg_point,
    closest_seg_seg,
    closest_seg_triangle,
    dist_derivs,
)
from sim.geometry.vec3 import vdot, vlerp, vmul, vsub
from sim.numba_options import OPT, OPT_ALLOC, OPT_CONTACT
from sim.scene.kinds import BOX, CAPSULE, MESH, PLANE, SPHERE

__all__ = ["find_candidates", "merge_candidates", "smallest_gap", "update_fraction", "node_forces", "contact_rows",
           "ObstacleContact", "alloc", "present", "candidates", "friction_acts", "broadphase", "refresh",
           "penetration", "step_limit", "accumulate", "energy", "report"]


@njit(**OPT_CONTACT)
def _to_local(p, R, x):
    d = (x[0] - p[0], x[1] - p[1], x[2] - p[2])
    return (R[0, 0] * d[0] + R[1, 0] * d[1] + R[2, 0] * d[2],
            R[0, 1] * d[0] + R[1, 1] * d[1] + R[2, 1] * d[2],
            R[0, 2] * d[0] + R[1, 2] * d[1] + R[2, 2] * d[2])


@njit(**OPT_CONTACT)
def _rot(R, v):
    return (R[0, 0] * v[0] + R[0, 1] * v[1] + R[0, 2] * v[2],
            R[1, 0] * v[0] + R[1, 1] * v[1] + R[1, 2] * v[2],
            R[2, 0] * v[0] + R[2, 1] * v[1] + R[2, 2] * v[2])


@njit(inline="always", **OPT_CONTACT)
def _box_lb2(lo0, lo1, lo2, hi0, hi1, hi2, slo, shi):
    """Squared distance between the box [lo, hi] and the box [slo, shi] (0 if they overlap)."""
    d0 = max(0.0, lo0 - shi[0], slo[0] - hi0)
    d1 = max(0.0, lo1 - shi[1], slo[1] - hi1)
    d2 = max(0.0, lo2 - shi[2], slo[2] - hi2)
    return d0 * d0 + d1 * d1 + d2 * d2


@njit(**OPT_CONTACT)
def _mesh_closest(al, bl, root, nlo, nhi, nch, nrg, tri, reach, stack):
    """Closest triangle of a mesh BVH to segment (al, bl) (local frame) within ``reach``.

    Nearest-first traversal: a node is skipped when the distance between its box and the segment's box
    exceeds the best distance found so far (or ``reach``), so the cost follows the triangles near the
    segment. Returns ``(dist, s, nfree, q, d1, d2, nrm)``; dist = inf when nothing is within reach.
    """
    z = (0.0, 0.0, 0.0)
    slo = (min(al[0], bl[0]), min(al[1], bl[1]), min(al[2], bl[2]))
    shi = (max(al[0], bl[0]), max(al[1], bl[1]), max(al[2], bl[2]))
    best = reach
    found = False
    bs = 0.0
    bnf = 0
    bq = z
    bd1 = z
    bd2 = z
    bn = z
    stack[0] = root
    sp = 1
    while sp > 0:
        sp -= 1
        nd = stack[sp]
        if _box_lb2(nlo[nd, 0], nlo[nd, 1], nlo[nd, 2], nhi[nd, 0], nhi[nd, 1], nhi[nd, 2], slo, shi) > best * best:
            continue
        if nch[nd, 0] < 0:
            st = nrg[nd, 0]
            for t in range(st, st + nrg[nd, 1]):
                v0 = (tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2])
                v1 = (tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2])
                v2 = (tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2])
                if _box_lb2(min(v0[0], v1[0], v2[0]), min(v0[1], v1[1], v2[1]), min(v0[2], v1[2], v2[2]),
                            max(v0[0], v1[0], v2[0]), max(v0[1], v1[1], v2[1]), max(v0[2], v1[2], v2[2]),
                            slo, shi) > best * best:
                    continue
                d, s, nf, q, d1, d2, nr = closest_seg_triangle(al, bl, v0, v1, v2)
                if d < best or (d <= best and not found):
                    best = d
                    found = True
                    bs = s
                    bnf = nf
                    bq = q
                    bd1 = d1
                    bd2 = d2
                    bn = nr
        elif sp + 2 <= stack.shape[0]:
            c0 = nch[nd, 0]
            c1 = nch[nd, 1]
            l0 = _box_lb2(nlo[c0, 0], nlo[c0, 1], nlo[c0, 2], nhi[c0, 0], nhi[c0, 1], nhi[c0, 2], slo, shi)
            l1 = _box_lb2(nlo[c1, 0], nlo[c1, 1], nlo[c1, 2], nhi[c1, 0], nhi[c1, 1], nhi[c1, 2], slo, shi)
            if l0 <= l1:  # push the farther child first: the nearer one is visited next
                stack[sp] = c1
                stack[sp + 1] = c0
            else:
                stack[sp] = c0
                stack[sp + 1] = c1
            sp += 2
    if not found:
        return np.inf, bs, bnf, bq, bd1, bd2, bn
    return best, bs, bnf, bq, bd1, bd2, bn


@njit(**OPT_CONTACT)
def _eval_edge(cd, e, o, a, b, r, reach, g6, H6, nhat, ws, stack, derivs=True):
    """Gap [m], closest rod parameter s and obstacle point of edge (a, b) vs obstacle o (not a plane).

    Fills g6/H6/nhat (derivatives of Delta, if ``derivs``) when the gap is < reach - r; returns
    gap = inf otherwise.
    """
    kind, p0, p1, rot = cd.kind, cd.p0, cd.p1, cd.rot
    rad, half, mroot, tri = cd.obstacle_radius, cd.half, cd.mesh_root, cd.tri
    nlo, nhi, nch, nrg = cd.node_lo, cd.node_hi, cd.node_child, cd.node_range
    z = (0.0, 0.0, 0.0)
    k = kind[o]
    P = (p0[e, o, 0], p0[e, o, 1], p0[e, o, 2])
    R = rad[e, o]
    if k == SPHERE:
        s = closest_seg_point(a, b, P)
        x = vlerp(a, b, s)
        dd = math.sqrt(vdot(vsub(x, P), vsub(x, P)))
        if dd - r - R >= reach - r:
            return np.inf, s, P
        if not derivs:
            return dd - r - R, s, P
        d = dist_derivs(a, b, s, P, 0, z, z, z, g6, H6, nhat, ws)
        return d - r - R, s, P
    if k == CAPSULE:
        Q = (p1[e, o, 0], p1[e, o, 1], p1[e, o, 2])
        s, u = closest_seg_seg(a, b, P, Q)
        x = vlerp(a, b, s)
        y = vlerp(P, Q, u)
        dd = math.sqrt(vdot(vsub(x, y), vsub(x, y)))
        if dd - r - R >= reach - r:
            return np.inf, s, y
        if not derivs:
            return dd - r - R, s, y
        nf = 1 if (u > 1e-12 and u < 1.0 - 1e-12) else 0
        d = dist_derivs(a, b, s, y, nf, vsub(Q, P), z, z, g6, H6, nhat, ws)
        return d - r - R, s, y
    Rm = rot[e, o]
    al = _to_local(P, Rm, a)
    bl = _to_local(P, Rm, b)
    if k == BOX:
        h = (half[o, 0], half[o, 1], half[o, 2])
        sd, s, mask, ql, nl = closest_seg_box(al, bl, h, ws)
        q = _rot(Rm, ql)
        q = (q[0] + P[0], q[1] + P[1], q[2] + P[2])
        if sd - r >= reach - r:
            return np.inf, s, q
        if not derivs:
            return sd - r, s, q
        if mask < 0:  # centre line inside the box: Gauss-Newton normal, no curvature term
            n = _rot(Rm, nl)
            for i in range(3):
                nhat[i] = n[i]
                g6[i] = (1.0 - s) * n[i]
                g6[3 + i] = s * n[i]
            H6[:, :] = 0.0
            return sd - r, s, q
        nf = 0
        d1 = z
        d2 = z
        for i in range(3):
            if mask & (1 << i):
                col = (Rm[0, i], Rm[1, i], Rm[2, i])
                if nf == 0:
                    d1 = col
                else:
                    d2 = col
                nf += 1
        d = dist_derivs(a, b, s, q, nf, d1, d2, z, g6, H6, nhat, ws)
        return d - r, s, q
    if k == MESH:
        dl, s, nf, ql, d1l, d2l, nl = _mesh_closest(al, bl, mroot[o], nlo, nhi, nch, nrg, tri, reach, stack)
        if dl == np.inf:
            return np.inf, s, z
        q = _rot(Rm, ql)
        q = (q[0] + P[0], q[1] + P[1], q[2] + P[2])
        if not derivs:
            return dl - r, s, q
        d = dist_derivs(a, b, s, q, nf, _rot(Rm, d1l), _rot(Rm, d2l), _rot(Rm, nl), g6, H6, nhat, ws)
        return d - r, s, q
    return np.inf, 0.0, z


@njit(**OPT_CONTACT)
def _box_face(cd, e, o, a, b):
    """The box face that both end points of segment (a, b) lie over (outside the box, each projecting along the
    face normal onto the face): returns (axis, side, d_a, d_b) with the nodes' distances to the face [m],
    else (-1, 0.0, 0.0, 0.0)."""
    P = (cd.p0[e, o, 0], cd.p0[e, o, 1], cd.p0[e, o, 2])
    Rm = cd.rot[e, o]
    al = _to_local(P, Rm, a)
    bl = _to_local(P, Rm, b)
    for i in range(3):
        hi = cd.half[o, i]
        for sg in (-1.0, 1.0):
            if sg * al[i] > hi and sg * bl[i] > hi:
                over = True
                for m in range(3):
                    if m != i and (abs(al[m]) > cd.half[o, m] or abs(bl[m]) > cd.half[o, m]):
                        over = False
                if over:
                    return i, sg, sg * al[i] - hi, sg * bl[i] - hi
    return -1, 0.0, 0.0, 0.0


@njit(**OPT_CONTACT)
def _mesh_face(cd, e, o, a, b, reach, stack):
    """The flat mesh region under both end points of segment (a, b): each node's closest mesh point within
    ``reach`` lies inside a triangle, both are seen along one common unit direction n (obstacle -> node, world
    frame) and lie in one plane normal to n (one face, or coplanar triangles). Returns (found, n, d_a, d_b) with
    the nodes' distances [m]."""
    z = (0.0, 0.0, 0.0)
    P = (cd.p0[e, o, 0], cd.p0[e, o, 1], cd.p0[e, o, 2])
    Rm = cd.rot[e, o]
    al = _to_local(P, Rm, a)
    bl = _to_local(P, Rm, b)
    root = cd.mesh_root[o]
    da, _, fa, qa, _, _, _ = _mesh_closest(al, al, root, cd.node_lo, cd.node_hi, cd.node_child, cd.node_range,
                                           cd.tri, reach, stack)
    if not (0.0 < da < reach and fa == 2):  # fa == 2: the closest point is inside a triangle
        return False, z, 0.0, 0.0
    db, _, fb, qb, _, _, _ = _mesh_closest(bl, bl, root, cd.node_lo, cd.node_hi, cd.node_child, cd.node_range,
                                           cd.tri, reach, stack)
    if not (0.0 < db < reach and fb == 2):
        return False, z, 0.0, 0.0
    ua = vmul(1.0 / da, vsub(al, qa))
    ub = vmul(1.0 / db, vsub(bl, qb))
    if vdot(ua, ub) < 1.0 - 1e-9 or abs(vdot(ua, vsub(qb, qa))) > 1e-9:
        return False, z, 0.0, 0.0
    return True, _rot(Rm, ua), da, db


@njit(**OPT_CONTACT)
def _flat_face(cd, e, o, a, b, reach, stack):
    """(found, unit normal n (world), d_a, d_b): the box face or flat mesh region under both nodes of the edge
    (a, b) and the nodes' distances to it [m]; see :func:`_box_face`, :func:`_mesh_face`."""
    if cd.kind[o] == BOX:
        fi, sg, da, db = _box_face(cd, e, o, a, b)
        if fi < 0:
            return False, (0.0, 0.0, 0.0), 0.0, 0.0
        return True, (sg * cd.rot[e, o, 0, fi], sg * cd.rot[e, o, 1, fi], sg * cd.rot[e, o, 2, fi]), da, db
    return _mesh_face(cd, e, o, a, b, reach, stack)


@njit(inline="always", **OPT_CONTACT)
def _scratch(cd, e):
    """Env ``e``'s distance scratch: (ws (64,), g6 (6,), nhat (3,), H6 (6, 6), BVH stack)."""
    scf = cd.scratch_f
    return scf[e, 0:64], scf[e, 64:70], scf[e, 70:73], cd.scratch_m[e, 0], cd.scratch_i[e]


@njit(inline="always", **OPT_CONTACT)
def _report_row(e, rc, j, o, rod_point, base, scale, n, ff, normal_force, gap, rows):
    """Write contact row ``rc`` of env ``e`` into ``rows``: edge ``j`` against obstacle ``o``, rod point
    ``rod_point``, obstacle surface point ``base + scale n``, normal ``n``, friction force ``ff``, normal force and
    gap."""
    rows.edge[e, rc] = j
    rows.obstacle[e, rc] = o
    for i in range(3):
        rows.rod_point[e, rc, i] = rod_point[i]
        rows.obstacle_point[e, rc, i] = base[i] + scale * n[i]
        rows.normal[e, rc, i] = n[i]
        rows.friction_force[e, rc, i] = ff[i]
    rows.normal_force[e, rc] = normal_force
    rows.gap[e, rc] = gap


@njit(inline="always", **OPT_CONTACT)
def _tally(e, rows, n, ff, normal_force):
    """Add a contact's force (normal force along ``n`` plus friction ``ff``) to env ``e``'s total in ``rows``."""
    for i in range(3):
        rows.force[e, i] += normal_force * n[i] + ff[i]


@njit(**OPT_CONTACT)
def _contact_pass(e, law, cd, x, x_prev, dt, radius, link, friction_on, grad, hess, rows):
    """One pass over env ``e``'s candidates at positions ``x``: returns the contact energy [J]; adds the residual
    and Jacobian blocks into ``grad``/``hess`` unless they are None; writes the contact rows and max penetration
    into ``rows`` unless it is None. ``law``: the contact law's parameters (a Params record: contact_k,
    contact_delta, friction, friction_nu)."""
    k, delta, mu, nu = law.contact_k, law.contact_delta, law.friction, law.friction_nu
    kind, p0, p1, rad = cd.kind, cd.p0, cd.p1, cd.obstacle_radius
    cand, ccount, scf, scm = cd.cand, cd.cand_count, cd.scratch_f, cd.scratch_m
    sci, fric = cd.scratch_i, cd.friction
    ws = scf[e, 0:64]
    g6 = scf[e, 64:70]
    nhat = scf[e, 70:73]
    fr = scf[e, 73:79]
    r0 = radius[0]
    uniform = radius.shape[0] == 1  # one radius for the whole rod: no per-candidate look-up
    H6 = scm[e, 0]
    Jf = scm[e, 1]
    stack = sci[e]
    N = x.shape[0]
    nc = ccount[e]
    energy = 0.0
    rc = 0
    cap = 0
    if rows is not None:
        cap = rows.gap.shape[1]
    maxpen = 0.0
    dropped = 0
    prev_j = -2
    prev_o = -1
    prev_gap = np.inf
    for c in range(nc):
        j = cand[e, c, 0]
        o = cand[e, c, 1]
        mu_o = fric[o] if fric[o] >= 0.0 else mu  # the obstacle's own μ, else the [contact] one
        r = r0 if uniform else (node_radius(radius, j) if kind[o] == PLANE else edge_radius(radius, j))
        do_fric = friction_on and mu_o > 0.0
        if kind[o] == PLANE:
            xk = row3(x, j)
            n = (p1[e, o, 0], p1[e, o, 1], p1[e, o, 2])
            gap = n[0] * (xk[0] - p0[e, o, 0]) + n[1] * (xk[1] - p0[e, o, 1]) + n[2] * (xk[2] - p0[e, o, 2]) - r
            if gap >= delta:
                continue
            E, dE, d2E = imc_energy(gap, k, delta)
            energy += E
            blk = j if j < N - 1 else N - 2
            sl = 3 * (j - blk)
            ff = (0.0, 0.0, 0.0)
            if do_fric:
                xp = row3(x_prev, j)
                v = ((xk[0] - xp[0]) / dt, (xk[1] - xp[1]) / dt, (xk[2] - xp[2]) / dt)
                ff = friction_block(v, v, 0.0, n, -dE, d2E, mu_o, nu, dt, fr, Jf)
            if grad is not None:
                for i in range(3):
                    grad[j, i] += dE * n[i]
                    for m in range(3):
                        hess[blk, sl + i, sl + m] += d2E * n[i] * n[m]
                if do_fric:
                    for i in range(3):
                        grad[j, i] += fr[i]
                        for m in range(3):
                            hess[blk, sl + i, sl + m] += Jf[i, m]
            if rows is not None:
                maxpen = max(maxpen, -gap)
                _tally(e, rows, n, ff, -dE)
                if rc < cap:
                    _report_row(e, rc, j, o, xk, xk, -(gap + r), n, ff, -dE, gap, rows)
                    rc += 1
                else:
                    dropped += 1
            continue
        a = row3(x, j)
        b = row3(x, j + 1)
        if kind[o] == BOX or kind[o] == MESH:
            face, n, da, db = _flat_face(cd, e, o, a, b, r + delta, stack)
            if face:
                # both nodes over one flat face: the segment's closest point would jump between its ends as the
                # edge tilts; act per node instead, like a plane (weight 1/2 at a node shared with the next or
                # previous edge, 1 at the rod's ends), which is smooth as the rod slides across the face
                prev_j = j
                prev_o = o
                prev_gap = db - r
                for end in range(2):
                    kk = j + end
                    gap = (da if end == 0 else db) - r
                    if gap >= delta:
                        continue
                    w = 1.0 if (end == 0 and j == 0) or (end == 1 and j == N - 2) else 0.5
                    if link is not None:  # a rod's end node next to a joint edge (several rods): its only edge
                        if (end == 0 and j > 0 and link[j - 1] == 0) or (end == 1 and j < N - 2 and link[j + 1] == 0):
                            w = 1.0
                    E, dE, d2E = imc_energy(gap, k, delta)
                    energy += w * E
                    dE *= w
                    d2E *= w
                    xk = row3(x, kk)
                    ff = (0.0, 0.0, 0.0)
                    if do_fric:
                        xp = row3(x_prev, kk)
                        v = ((xk[0] - xp[0]) / dt, (xk[1] - xp[1]) / dt, (xk[2] - xp[2]) / dt)
                        ff = friction_block(v, v, float(end), n, -dE, d2E, mu_o, nu, dt, fr, Jf)
                    if grad is not None:
                        for i in range(3):
                            grad[kk, i] += dE * n[i]
                            for m in range(3):
                                hess[j, 3 * end + i, 3 * end + m] += d2E * n[i] * n[m]
                        if do_fric:
                            for i in range(6):
                                grad[j + i // 3, i % 3] += fr[i]
                                for m in range(6):
                                    hess[j, i, m] += Jf[i, m]
                    if rows is not None:
                        maxpen = max(maxpen, -gap)
                        _tally(e, rows, n, ff, -dE)
                        if rc < cap:
                            _report_row(e, rc, j, o, xk, xk, -(gap + r), n, ff, -dE, gap, rows)
                            rc += 1
                        else:
                            dropped += 1
                continue
        gap, s, q = _eval_edge(cd, e, o, a, b, r, r + delta, g6, H6, nhat, ws, stack)
        keep = gap < delta
        if keep and s >= 1.0 and j < N - 2 and c + 1 < nc and cand[e, c + 1, 0] == j + 1 \
                and cand[e, c + 1, 1] == o:
            keep = False  # the next edge owns its start node
        if keep and s <= 0.0 and prev_j == j - 1 and prev_o == o and prev_gap < gap - 1e-10:
            keep = False  # the previous edge holds a strictly closer point: node j is no local minimum
        prev_j = j
        prev_o = o
        prev_gap = gap
        if not keep:
            continue
        E, dE, d2E = imc_energy(gap, k, delta)
        energy += E
        n = (nhat[0], nhat[1], nhat[2])
        ff = (0.0, 0.0, 0.0)
        if do_fric:
            xa0 = row3(x_prev, j)
            xb0 = row3(x_prev, j + 1)
            va = ((a[0] - xa0[0]) / dt, (a[1] - xa0[1]) / dt, (a[2] - xa0[2]) / dt)
            vb = ((b[0] - xb0[0]) / dt, (b[1] - xb0[1]) / dt, (b[2] - xb0[2]) / dt)
            ff = friction_block(va, vb, s, n, -dE, d2E, mu_o, nu, dt, fr, Jf)
        if grad is not None:
            for i in range(3):
                grad[j, i] += dE * g6[i]
                grad[j + 1, i] += dE * g6[3 + i]
            for i in range(6):
                for m in range(6):
                    hess[j, i, m] += d2E * g6[i] * g6[m] + dE * H6[i, m]
            if do_fric:
                for i in range(3):
                    grad[j, i] += fr[i]
                    grad[j + 1, i] += fr[3 + i]
                for i in range(6):
                    for m in range(6):
                        hess[j, i, m] += Jf[i, m]
        if rows is not None:
            maxpen = max(maxpen, -gap)
            _tally(e, rows, n, ff, -dE)
            if rc < cap:
                xr = vlerp(a, b, s)
                # q is the closest point of a sphere's centre / a capsule's axis: step out to its surface
                ro = rad[e, o] if (kind[o] == SPHERE or kind[o] == CAPSULE) else 0.0
                _report_row(e, rc, j, o, xr, q, ro, n, ff, -dE, gap, rows)
                rc += 1
            else:
                dropped += 1
    if rows is not None:
        rows.count[e] = rc
        rows.max_penetration[e] = maxpen
        rows.dropped[e] += dropped
    return energy


@njit(**OPT_CONTACT)
def _plane_gap(cd, e, o, xx, kk):
    p0 = cd.p0
    p1 = cd.p1
    return (p1[e, o, 0] * (xx[kk, 0] - p0[e, o, 0]) + p1[e, o, 1] * (xx[kk, 1] - p0[e, o, 1])
            + p1[e, o, 2] * (xx[kk, 2] - p0[e, o, 2]))


@njit(**OPT_CONTACT)
def find_candidates(e, cd, x_start, x_guess, margin, link=None):
    """Fill env ``e``'s candidate list: pairs whose gap may fall below ``margin`` [m] anywhere on the straight
    path from ``x_start`` to ``x_guess`` (one test at the midway configuration, inflated by half the motion). Pass as ``x_guess`` the predicted end of the (sub)step ``x0 + h u`` so that the list covers
    the motion of the step (the Newton guess x0 + 0.01 h u also works for slow motion).

    ``link`` (N-1,) (optional, RodData.link): edges with 0 are joint edges between two rods of a scene, which carry
    no material and are never candidates (planes test nodes, which all belong to a rod).

    Candidates are (edge j, obstacle o) for non-plane obstacles and (node k, plane o), stored
    obstacle-major with increasing j (the ownership rule relies on that order). Returns the count.
    """
    kind, cand, ccount = cd.kind, cd.cand, cd.cand_count
    active, obox = cd.active, cd.box
    r = cd.broadphase_radius[0]
    N = x_start.shape[0]
    M = kind.shape[0]
    cap = cand.shape[1]
    ws, g6, nhat, H6, stack = _scratch(cd, e)
    infl = r + margin
    # rod AABB over both configurations
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    for k in range(N):
        lo0 = min(lo0, x_start[k, 0], x_guess[k, 0])
        lo1 = min(lo1, x_start[k, 1], x_guess[k, 1])
        lo2 = min(lo2, x_start[k, 2], x_guess[k, 2])
        hi0 = max(hi0, x_start[k, 0], x_guess[k, 0])
        hi1 = max(hi1, x_start[k, 1], x_guess[k, 1])
        hi2 = max(hi2, x_start[k, 2], x_guess[k, 2])
    cnt = 0
    for o in range(M):
        if not active[e, o]:
            continue
        if (obox[e, o, 0, 0] > hi0 + infl or obox[e, o, 1, 0] < lo0 - infl or obox[e, o, 0, 1] > hi1 + infl
                or obox[e, o, 1, 1] < lo1 - infl or obox[e, o, 0, 2] > hi2 + infl
                or obox[e, o, 1, 2] < lo2 - infl):
            continue
        kd = kind[o]
        if kd == PLANE:
            for kk in range(N):
                best = min(_plane_gap(cd, e, o, x_start, kk), _plane_gap(cd, e, o, x_guess, kk)) - r
                if best < margin and cnt < cap:
                    cand[e, cnt, 0] = kk
                    cand[e, cnt, 1] = o
                    cnt += 1
            continue
        for j in range(N - 1):
            if link is not None:
                if link[j] == 0:
                    continue
            # edge AABB (both configurations) against the obstacle AABB
            elo0 = min(x_start[j, 0], x_start[j + 1, 0], x_guess[j, 0], x_guess[j + 1, 0]) - infl
            ehi0 = max(x_start[j, 0], x_start[j + 1, 0], x_guess[j, 0], x_guess[j + 1, 0]) + infl
            elo1 = min(x_start[j, 1], x_start[j + 1, 1], x_guess[j, 1], x_guess[j + 1, 1]) - infl
            ehi1 = max(x_start[j, 1], x_start[j + 1, 1], x_guess[j, 1], x_guess[j + 1, 1]) + infl
            elo2 = min(x_start[j, 2], x_start[j + 1, 2], x_guess[j, 2], x_guess[j + 1, 2]) - infl
            ehi2 = max(x_start[j, 2], x_start[j + 1, 2], x_guess[j, 2], x_guess[j + 1, 2]) + infl
            if (obox[e, o, 0, 0] > ehi0 or obox[e, o, 1, 0] < elo0 or obox[e, o, 0, 1] > ehi1
                    or obox[e, o, 1, 1] < elo1 or obox[e, o, 0, 2] > ehi2 or obox[e, o, 1, 2] < elo2):
                continue
            # midway configuration; every configuration on the straight path start -> predicted end is
            # within dmax (half the larger node motion) of it, and the gap is 1-Lipschitz in node motion
            a = vlerp(row3(x_start, j), row3(x_guess, j), 0.5)
            b = vlerp(row3(x_start, j + 1), row3(x_guess, j + 1), 0.5)
            da = vsub(row3(x_guess, j), row3(x_start, j))
            db = vsub(row3(x_guess, j + 1), row3(x_start, j + 1))
            dmax = 0.5 * math.sqrt(max(vdot(da, da), vdot(db, db)))
            gap, s, q = _eval_edge(cd, e, o, a, b, r, r + margin + dmax, g6, H6, nhat, ws, stack, False)
            hit = gap < margin + dmax
            if hit and cnt < cap:
                cand[e, cnt, 0] = j
                cand[e, cnt, 1] = o
                cnt += 1
    ccount[e] = cnt
    return cnt


@njit(**OPT_CONTACT)
def merge_candidates(e, cd, x_start, x_end, margin, link=None):
    """Re-run the broad phase of env ``e`` over the motion ``x_start`` -> ``x_end`` (the solved end of a step)
    and merge it with the current list. Returns True if that added pairs (the caller then solves again).

    The list built from the predicted motion x0 + h·u misses obstacles that a control change moves the rod
    onto within the step; this catches them (and the guard then sees their penetration). The merged list
    keeps the broad phase's order (obstacle-major, increasing edge/node index), truncated at capacity.
    ``link``: as for :func:`find_candidates`.
    """
    cand = cd.cand
    ccount = cd.cand_count
    cap = cand.shape[1]
    n1 = ccount[e]
    old = cd.cand_merge[e, :cap]  # the current list, kept while the broad phase rewrites cand[e]
    for c in range(n1):
        old[c, 0] = cand[e, c, 0]
        old[c, 1] = cand[e, c, 1]
    n2 = find_candidates(e, cd, x_start, x_end, margin, link)
    new = cd.cand_merge[e, cap:]
    for c in range(n2):
        new[c, 0] = cand[e, c, 0]
        new[c, 1] = cand[e, c, 1]
    # merge two (obstacle, index)-sorted lists without duplicates
    i = 0
    k = 0
    cnt = 0
    added = False
    while (i < n1 or k < n2) and cnt < cap:
        if k >= n2:
            take_old = True
        elif i >= n1:
            take_old = False
        else:
            take_old = (old[i, 1] < new[k, 1]) or (old[i, 1] == new[k, 1] and old[i, 0] <= new[k, 0])
        if take_old:
            cand[e, cnt, 0] = old[i, 0]
            cand[e, cnt, 1] = old[i, 1]
            if k < n2 and old[i, 0] == new[k, 0] and old[i, 1] == new[k, 1]:
                k += 1
            i += 1
        else:
            cand[e, cnt, 0] = new[k, 0]
            cand[e, cnt, 1] = new[k, 1]
            added = True
            k += 1
        cnt += 1
    ccount[e] = cnt
    return added


@njit(**OPT_CONTACT)
def _pair_gap(cd, e, c, x, dxp, t, radius, reach, g6, H6, nhat, ws, stack):
    """Gap [m] of candidate c of env e at node positions x + t·dxp ((N, 3) arrays); an edge's gap of ``reach`` [m]
    or more may come back as inf."""
    cand = cd.cand
    j = cand[e, c, 0]
    o = cand[e, c, 1]
    a = (x[j, 0] + t * dxp[j, 0], x[j, 1] + t * dxp[j, 1], x[j, 2] + t * dxp[j, 2])
    if cd.kind[o] == PLANE:
        p0 = cd.p0
        p1 = cd.p1
        return (p1[e, o, 0] * (a[0] - p0[e, o, 0]) + p1[e, o, 1] * (a[1] - p0[e, o, 1])
                + p1[e, o, 2] * (a[2] - p0[e, o, 2])) - node_radius(radius, j)
    r = edge_radius(radius, j)
    b = (x[j + 1, 0] + t * dxp[j + 1, 0], x[j + 1, 1] + t * dxp[j + 1, 1], x[j + 1, 2] + t * dxp[j + 1, 2])
    gap, s, q = _eval_edge(cd, e, o, a, b, r, reach + r, g6, H6, nhat, ws, stack, False)
    return gap


@njit(**OPT_CONTACT)
def update_fraction(e, cd, x, dxp, radius, delta):
    """Largest fraction t ∈ (0, 1] of the Newton update ``dxp`` ((N, 3) node displacements from positions
    ``x``) that lets no candidate pair of env ``e`` go deeper than max-penetration allowance: a pair with
    gap g0 at t = 0 may reach min(g0, 0) − δ, not below. So one update can neither jump a rod edge across an
    obstacle (tunnelling: both end states outside, the path through it) nor push a penetrating pair more
    than δ deeper; the IMC force acts again at the next iteration. Conservative advancement: the gap of an
    edge against a fixed obstacle is 1-Lipschitz in the larger end-node displacement D, so steps of
    (g(t) − floor)/D never pass the first time the floor is reached.
    """
    kind, p1, cand, ccount = cd.kind, cd.p1, cd.cand, cd.cand_count
    ws, g6, nhat, H6, stack = _scratch(cd, e)
    tmax = 1.0
    for c in range(ccount[e]):
        j = cand[e, c, 0]
        D = math.sqrt(dxp[j, 0] ** 2 + dxp[j, 1] ** 2 + dxp[j, 2] ** 2)
        if kind[cand[e, c, 1]] != PLANE:
            D = max(D, math.sqrt(dxp[j + 1, 0] ** 2 + dxp[j + 1, 1] ** 2 + dxp[j + 1, 2] ** 2))
        if D <= 0.0:
            continue
        reach = D * tmax + 2.0 * delta   # gaps beyond reach cannot reach the floor (returned as inf)
        g = _pair_gap(cd, e, c, x, dxp, 0.0, radius, reach, g6, H6, nhat, ws, stack)
        floor = min(g, 0.0) - delta
        if g - D * tmax >= floor:   # cannot reach the floor within the allowed fraction
            continue
        o = cand[e, c, 1]
        if kind[o] == PLANE:        # the gap is linear along the update: exact fraction
            rate = p1[e, o, 0] * dxp[j, 0] + p1[e, o, 1] * dxp[j, 1] + p1[e, o, 2] * dxp[j, 2]
            if rate < 0.0:
                tmax = min(tmax, (g - floor) / -rate)
            continue
        t = 0.0
        for _ in range(256):        # tangential sliding advances by about delta / D per pass
            step = (g - floor) / D
            if step < 1e-3 * delta / D:   # at the floor (to 0.1 % of delta)
                break
            t += step
            if t >= tmax:
                break
            g = _pair_gap(cd, e, c, x, dxp, t, radius, reach, g6, H6, nhat, ws, stack)
        if t < tmax:
            tmax = t
    return max(tmax, 1e-3)


@njit(**OPT_CONTACT)
def node_forces(e, law, cd, x, x_prev, dt, radius, friction_on, grad, hess, link=None):
    """Add the contact (+ friction) residual into ``grad`` (N, 3) [N] and Jacobian blocks into ``hess``
    (N-1, 6, 6) [N/m] for env ``e``'s candidates at positions ``x``; return the contact energy [J]. ``law``: the
    contact law (a Params record).

    Friction (if ``friction_on``) at every iterate, the first one included (docs/physics.md §4.6). ``link``
    (optional, RodData.link): tells a rod's end nodes next to a joint edge (several rods) for the flat-face
    weights."""
    return _contact_pass(e, law, cd, x, x_prev, dt, radius, link, friction_on, grad, hess, None)


@njit(**OPT_CONTACT)
def smallest_gap(e, cd, x, radius):
    """Smallest negative gap [m] over env ``e``'s current candidates at node positions ``x`` (N, >=3) [m];
    0.0 when no candidate penetrates (so the max penetration is ``-smallest_gap``).

    No derivatives and no ownership filter (dropping non-minimal pairs cannot change the minimum), so
    ``-smallest_gap`` equals :func:`contact_rows`' max penetration for the same positions and candidates.
    """
    kind, cand, ccount = cd.kind, cd.cand, cd.cand_count
    ws, g6, nhat, H6, stack = _scratch(cd, e)
    best = 0.0
    for c in range(ccount[e]):
        j = cand[e, c, 0]
        o = cand[e, c, 1]
        if kind[o] == PLANE:
            gap = _plane_gap(cd, e, o, x, j) - node_radius(radius, j)
        else:
            r = edge_radius(radius, j)
            gap, s, q = _eval_edge(cd, e, o, row3(x, j), row3(x, j + 1), r, r, g6, H6, nhat, ws, stack, False)
        if gap < best:
            best = gap
    return best


@njit(**OPT_CONTACT)
def contact_rows(e, law, cd, x, x_prev, dt, radius, friction_on, rows, link=None):
    """Fill env ``e``'s contact rows in ``rows`` (a :class:`sim.kernels.data.ContactReport`, up to its capacity C),
    its max penetration [m], and over every contact, listed or not, the rows dropped and the total force on the rod
    (added to ``rows.dropped``/``rows.force``); return the energy [J].

    Rows: edge (node for planes), obstacle, rod point (on the rod's centre line) [m], obstacle point (the
    closest point on the obstacle's surface, for every kind) [m], unit normal (obstacle -> rod),
    normal force magnitude [N], friction force on the rod [N] (3,), gap [m]. Velocities (x - x_prev)/dt.
    """
    return _contact_pass(e, law, cd, x, x_prev, dt, radius, link, friction_on, None, None, rows)


# ------------------------------------------------------------------------------------- the contact protocol
ObstacleContact = namedtuple("ObstacleContact", ["data", "force", "jac"])
ObstacleContact.__doc__ = """Obstacle contact as the Newton stages see it: ``data`` the obstacles' ContactData (all
envs), and one thread's scratch for the node forces: ``force`` (N, 3) and the per-edge Jacobian blocks ``jac``
(N-1, 6, 6)."""


@njit(**OPT_ALLOC)
def alloc(cd, N):
    """One thread's :class:`ObstacleContact` for a rod of N nodes."""
    return ObstacleContact(cd, np.zeros((N, 3)), np.zeros((N - 1, 6, 6)))


@njit(inline="always", **OPT_CONTACT)
def present(prm):
    """Whether the scene has obstacle contact."""
    return prm.n_obstacles > 0


@njit(inline="always", **OPT_CONTACT)
def candidates(e, oc):
    """Env ``e``'s candidate count."""
    return oc.data.cand_count[e]


@njit(inline="always", **OPT_CONTACT)
def friction_acts(prm):
    """Whether friction can act (some obstacle has μ > 0)."""
    return prm.friction_on


@njit(inline="always", **OPT_CONTACT)
def broadphase(e, prm, rod, oc, pos0, pos):
    """Env ``e``'s candidates over the motion pos0 → pos."""
    find_candidates(e, oc.data, pos0, pos, prm.contact_margin, rod.link)


@njit(inline="always", **OPT_CONTACT)
def refresh(e, prm, rod, oc, pos0, pos):
    """Candidates over the motion pos0 → pos merged into the list: (whether pairs were added, whether the (sub)step
    must be solved again: so they were)."""
    added = merge_candidates(e, oc.data, pos0, pos, prm.contact_margin, rod.link)
    return added, added


@njit(inline="always", **OPT_CONTACT)
def penetration(e, prm, rod, oc, pos):
    """Deepest penetration [m] (≥ 0) of env ``e``'s candidates at ``pos``."""
    return -smallest_gap(e, oc.data, pos, rod.edge_radius)


@njit(inline="always", **OPT_CONTACT)
def step_limit(e, prm, rod, oc, pos, dpos):
    """Largest fraction of the node update ``dpos`` that lets no candidate tunnel (:func:`update_fraction`)."""
    return update_fraction(e, oc.data, pos, dpos, rod.edge_radius, prm.contact_delta)


@njit(**OPT)
def accumulate(e, prm, rod, oc, w, h, with_jac, sym):
    """Add the contact residual into ``w.f`` and (``with_jac``) its Jacobian into the band ``w.ab`` (upper half with
    ``sym``) at the nodes w.pos, velocities from w.pos0 over h; returns the energy [J]. The node forces act on the
    DOFs of the mode (planar: x, z; the y component is dropped)."""
    force, jac = oc.force, oc.jac
    force[:, :] = 0.0
    jac[:, :, :] = 0.0
    ec = node_forces(e, prm, oc.data, w.pos, w.pos0, h, rod.edge_radius, prm.friction_on, force, jac, rod.link)
    f, ab = w.f, w.ab
    N = force.shape[0]
    if prm.planar:
        kl = ab.shape[1] // 2
        for k in range(N):
            f[2 * k] += force[k, 0]
            f[2 * k + 1] += force[k, 2]
        if with_jac:
            for j in range(N - 1):
                for a in range(4):
                    la = (a // 2) * 3 + (0 if a % 2 == 0 else 2)
                    r = 2 * j + a
                    for b in range(a if sym else 0, 4):
                        lb = (b // 2) * 3 + (0 if b % 2 == 0 else 2)
                        c = 2 * j + b
                        ab[r, kl + c - r] += jac[j, la, lb]
    else:
        kl = ab.shape[1] // 2
        for k in range(N):
            for a in range(3):
                f[4 * k + a] += force[k, a]
        if with_jac:
            for j in range(N - 1):
                for a in range(6):
                    r = 4 * j + a if a < 3 else 4 * j + 1 + a
                    for b in range(a if sym else 0, 6):
                        c = 4 * j + b if b < 3 else 4 * j + 1 + b
                        ab[r, kl + c - r] += jac[j, a, b]
    return ec


@njit(inline="always", **OPT_CONTACT)
def energy(e, prm, rod, oc, pos, pos0, h):
    """Contact energy [J] of env ``e``'s candidates at ``pos`` (friction off)."""
    return node_forces(e, prm, oc.data, pos, pos0, h, rod.edge_radius, False, oc.force, oc.jac, rod.link)


@njit(inline="always", **OPT_CONTACT)
def report(e, prm, rod, oc, pos, pos0, rows):
    """Env ``e``'s contact rows at the state kept (``pos``; velocities from pos0 over the step) over a fresh
    candidate list, written first in ``rows`` with the max penetration; returns the energy [J]."""
    find_candidates(e, oc.data, pos, pos, prm.contact_margin, rod.link)
    return contact_rows(e, prm, oc.data, pos, pos0, prm.dt, rod.edge_radius, prm.friction_on, rows, rod.link)
