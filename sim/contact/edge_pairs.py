"""Rod–rod and self-contact: IMC potential and friction between pairs of rod edges (docs/physics.md §4.8).

Each edge is a capsule of its radius. For an allowed pair of edges (i, j) (:func:`allowed_pairs`: both material
edges, not neighbours along one rod) the gap is ``g = Δ − r_i − r_j`` with ``Δ`` the exact distance between the two
centre-line segments (Lumelsky's closest points, docs/physics.md §4.2) and the energy the IMC softplus-squared
``E(g)`` of the obstacles (:func:`sim.contact.imc.imc_energy`). ``Δ``'s gradient and Hessian over the 12
coordinates of the pair's four nodes follow from the envelope theorem and a Schur complement over the closest-point
parameters that are interior (:func:`seg_seg_derivs`), so the Newton Jacobian is exact inside each region
(point–point, point–edge, edge–edge).

A pair couples nodes far apart along the chain, outside the band of the banded Jacobian. The assembly
(:func:`add_forces`) adds the blocks of each edge with itself into the band and collects the blocks
between the two edges, entry by entry over the DOFs they touch, into a small dense coupling matrix ``M`` over a
list of those DOFs (:class:`Coupling`, the Workspace's ``coupling``); :mod:`sim.kernels.newton` then solves ``(B + E M Eᵀ) dx = f``
by the Woodbury identity on the banded factorisation of ``B`` (:func:`sim.kernels.newton._woodbury`). With no pair
within reach the list is empty and the solve is the banded one.

Candidates: once per (sub)step, over the predicted motion, every allowed pair whose swept boxes (each edge's box over
the step's start and end, grown by its radius and half the contact margin) overlap (:func:`find_candidates`);
refreshed over the motion actually taken like the obstacle candidates (:func:`add_candidates`).

One crossing, one contact (§4.8): each rod's centre line counts as its edges less its interior nodes, so a crossing on
a node (the closest point of 2 pairs, or of 4 on a node of both rods) is one contact: pair (i, j) carries its
edges' term and the −E / +E terms of the start nodes it owns (:func:`_terms`, :func:`pair_links`); a node is a
segment of zero length in the same distance functions.

Friction (IMC friction, §4.6, lagged normal and closest-point weights): the contact points' relative velocity
``v = Σ c_k v_k`` with weights ``c = (1−s, s, −(1−t), −t)`` on the nodes (x_i, x_{i+1}, x_j, x_{j+1}); residual
``μ λ γ(|v_t|) c_k t̂`` on node k, ``λ = −E'(g)``.

Positions are (N, 3) arrays; ``dpn`` DOFs per node: 4 (3-D: [x, y, z, θ]) or 2 (planar: [x, z], y fixed); ``law``
the contact law's parameters (a Params record: contact_k, contact_delta, friction, friction_nu).

The end of the module is the contact protocol (:mod:`sim.contact.stages`) for edge pairs: the same functions, with
the same arguments, as :mod:`sim.contact.obstacles`, on an :class:`EdgePairContact`.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from sim.contact.imc import coulomb_factor, edge_radius, friction_tangent_entry, imc_energy, row3
from sim.geometry.distance import closest_seg_seg
from sim.geometry.vec3 import vcross, vdot, vlerp, vsub
from sim.numba_options import OPT_ALLOC, OPT_CONTACT

__all__ = ["allowed_pairs", "model_pairs", "pair_links", "edge_rods", "seg_seg_derivs", "find_candidates", "add_candidates",
           "pair_gap",
           "add_forces", "smallest_gap", "pair_energy", "pair_rows", "update_fraction", "Coupling", "alloc_coupling",
           "reset_coupling", "EdgePairContact", "alloc", "present", "candidates", "friction_acts", "broadphase",
           "refresh", "penetration", "step_limit", "accumulate", "energy", "report"]

_EPS_PARAM = 1e-9  # a closest-point parameter this close to 0 or 1 counts as at the segment's end

EdgePairContact = namedtuple("EdgePairContact", ["cand", "count", "box", "g12", "H12", "nhat", "ws"])
EdgePairContact.__doc__ = """Edge-pair contact as the Newton stages see it (one thread's): candidate pair indices
``cand`` (P,) into the allowed pairs and their ``count`` (1,), edge boxes ``box`` (N-1, 6), a pair's distance
derivatives ``g12`` (12,), ``H12`` (12, 12), normal ``nhat`` (3,) and scratch ``ws`` (32,)."""

Coupling = namedtuple("Coupling", ["slot", "dof", "count", "M", "Z", "C", "r", "piv"])
Coupling.__doc__ = """The Jacobian's coupling outside the band (docs/physics.md §4.8), filled by :func:`add_forces` and
solved by the Woodbury correction of sim.kernels.newton: DOF → list slot ``slot`` (n,) (-1: not listed), listed
DOFs ``dof`` (K,) and their ``count`` (1,), coupling matrix ``M`` (K, K); the solve's scratch: B⁻¹ columns ``Z``
(K, n + kl), capacitance ``C`` (K, K), its right-hand side ``r`` (K,) and pivots ``piv`` (K,). K = 3N (3-D) or 2N
(planar) position DOFs; all empty without edge pairs."""


def allowed_pairs(rest_edge_length: np.ndarray, edge_radius: np.ndarray, edge_rod: np.ndarray, *,
                  self_contact: bool, rod_contact: bool, delta: float) -> np.ndarray:
    """Edge pairs (i, j), i < j, that may touch: (P, 2) int64.

    ``edge_rod`` (E,): the rod of each edge (−1 for a joint edge between two rods, which never touches).
    Pairs of one rod (only with ``self_contact``) are left out when they are neighbours along it: the rest arc
    length between the end of edge i and the start of edge j is below the contact distance r_i + r_j + δ (such
    edges touch whenever the rod is straight), and always when they share a node. Pairs of two rods need
    ``rod_contact``.
    """
    lbar = np.asarray(rest_edge_length, dtype=np.float64)
    r = np.asarray(edge_radius, dtype=np.float64)
    rod = np.asarray(edge_rod, dtype=np.int64)
    E = lbar.shape[0]
    if r.shape[0] == 1:
        r = np.full(E, r[0])
    arc_end = np.cumsum(np.where(rod >= 0, lbar, 0.0))   # rest arc length at each edge's end (joints add none)
    arc_start = arc_end - np.where(rod >= 0, lbar, 0.0)
    out = []
    for i in range(E):
        if rod[i] < 0:
            continue
        for j in range(i + 1, E):
            if rod[j] < 0:
                continue
            if rod[i] == rod[j]:
                if not self_contact or j - i < 2:
                    continue
                if arc_start[j] - arc_end[i] < r[i] + r[j] + delta:
                    continue
            elif not rod_contact:
                continue
            out.append((i, j))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def edge_rods(model) -> np.ndarray:
    """(N-1,) int64: the rod of each edge of ``model``'s chain, −1 for a joint edge between two rods."""
    E = model.node_count - 1
    offsets = getattr(model, "rod_node_offsets", None)
    if offsets is None or len(offsets) <= 2:
        return np.zeros(E, dtype=np.int64)
    out = np.full(E, -1, dtype=np.int64)
    for r in range(len(offsets) - 1):
        out[int(offsets[r]):int(offsets[r + 1]) - 1] = r
    return out


def model_pairs(model) -> np.ndarray:
    """The edge pairs of ``model`` that may touch (:func:`allowed_pairs` with its ``[contact]`` switches):
    ``self_contact`` (default off), ``rod_contact`` (default on when there are several rods); none when contact is
    disabled."""
    c = model.spec.contact
    rods = edge_rods(model)
    several = rods.max(initial=0) > 0
    rod_contact = several if c.rod_contact is None else bool(c.rod_contact) and several
    if not getattr(c, "enabled", True) or not (c.self_contact or rod_contact):
        return np.zeros((0, 2), dtype=np.int64)
    return allowed_pairs(model.rest_edge_length, model.edge_radius, rods, self_contact=bool(c.self_contact),
                         rod_contact=rod_contact, delta=float(c.delta))


def pair_links(pairs: np.ndarray) -> np.ndarray:
    """(P, 3) int64: for each allowed pair (i, j) of ``pairs`` (P, 2), the index in ``pairs`` of the pairs
    (i − 1, j), (i, j − 1) and (i − 1, j − 1), or −1 where that pair is not allowed (the edge before is on another
    rod, a joint edge, or too close along the rod). They decide which node terms pair (i, j) carries
    (:func:`_terms`)."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    index = {(int(i), int(j)): c for c, (i, j) in enumerate(pairs)}
    out = np.full((pairs.shape[0], 3), -1, dtype=np.int64)
    for c, (i, j) in enumerate(pairs):
        for slot, (a, b) in enumerate(((i - 1, j), (i, j - 1), (i - 1, j - 1))):
            if a != b:
                out[c, slot] = index.get((min(int(a), int(b)), max(int(a), int(b))), -1)
    return out


@njit(**OPT_CONTACT)
def seg_seg_derivs(a, b, p, q, grad, hess, nhat, ws):
    """Distance Δ [m] between segments (a, b) and (p, q) (3-tuples) with its gradient ``grad`` (12,) and Hessian
    ``hess`` (12, 12) over (a, b, p, q), and the unit normal ``nhat`` (3,) from the (p, q) point to the (a, b)
    point. Returns (Δ, s, t): the closest points are a + s (b − a) and p + t (q − p).

    D = |u|², u = (1−s) a + s b − (1−t) p − t q. At the minimum over the interior parameters y ⊂ {s, t},
    ∇(D/2) = Jᵀu (J = ∂u/∂x = [(1−s) I, s I, −(1−t) I, −t I]) and ∇²(D/2) = JᵀJ − D_xy D_yy⁻¹ D_yx with
    D_yy = GᵀG (G = ∂u/∂y: e1 = b − a for s, −e2 = p − q for t) and D_xy the mixed derivative
    (Jᵀ G + ∂G/∂xᵀ u); then ∇Δ = ∇(D/2)/Δ and ∇²Δ = (∇²(D/2) − ∇Δ∇Δᵀ)/Δ. ``ws`` (≥ 30,) is scratch.
    Touching centre lines (Δ ≈ 0) have no normal: ``nhat`` is then e1 × e2 (or a direction ⟂ e1) and the
    Hessian is left 0.
    """
    s, t = closest_seg_seg(a, b, p, q)
    c0 = 1.0 - s
    c1 = s
    c2 = -(1.0 - t)
    c3 = -t
    u = vsub(vlerp(a, b, s), vlerp(p, q, t))
    dd = math.sqrt(vdot(u, u))
    e1 = vsub(b, a)
    e2 = vsub(q, p)
    for r in range(12):
        for c in range(12):
            hess[r, c] = 0.0
    scale = max(math.sqrt(vdot(e1, e1)), math.sqrt(vdot(e2, e2)), 1e-300)
    if dd <= 1e-12 * scale:
        n = vcross(e1, e2)
        nn = math.sqrt(vdot(n, n))
        if nn <= 1e-12 * scale * scale:
            ax = 0
            if abs(e1[1]) < abs(e1[ax]):
                ax = 1
            if abs(e1[2]) < abs(e1[ax]):
                ax = 2
            n = vcross(e1, (1.0 if ax == 0 else 0.0, 1.0 if ax == 1 else 0.0, 1.0 if ax == 2 else 0.0))
            nn = math.sqrt(vdot(n, n))
            if nn <= 0.0:  # two nodes (zero-length segments: node terms) at one point: any direction
                n = (0.0, 0.0, 1.0)
                nn = 1.0
        for i in range(3):
            nhat[i] = n[i] / nn
            grad[i] = c0 * nhat[i]
            grad[3 + i] = c1 * nhat[i]
            grad[6 + i] = c2 * nhat[i]
            grad[9 + i] = c3 * nhat[i]
        return 0.0, s, t
    inv = 1.0 / dd
    for i in range(3):
        nhat[i] = u[i] * inv
        grad[i] = c0 * nhat[i]
        grad[3 + i] = c1 * nhat[i]
        grad[6 + i] = c2 * nhat[i]
        grad[9 + i] = c3 * nhat[i]
    cw = (c0, c1, c2, c3)
    for k in range(4):  # JᵀJ
        for m in range(4):
            v = cw[k] * cw[m]
            for i in range(3):
                hess[3 * k + i, 3 * m + i] = v
    # columns of D_xy/2 over the interior parameters: ws[12 m + r] (m = 0, 1), G columns at ws[24 + 3 m + i]
    nf = 0
    if _EPS_PARAM < s < 1.0 - _EPS_PARAM:
        for i in range(3):
            ws[i] = c0 * e1[i] - u[i]
            ws[3 + i] = c1 * e1[i] + u[i]
            ws[6 + i] = c2 * e1[i]
            ws[9 + i] = c3 * e1[i]
            ws[24 + i] = e1[i]
        nf = 1
    if _EPS_PARAM < t < 1.0 - _EPS_PARAM:
        o = 12 * nf
        for i in range(3):
            ws[o + i] = -c0 * e2[i]
            ws[o + 3 + i] = -c1 * e2[i]
            ws[o + 6 + i] = -c2 * e2[i] + u[i]
            ws[o + 9 + i] = -c3 * e2[i] - u[i]
            ws[24 + 3 * nf + i] = -e2[i]
        nf += 1
    if nf == 1:
        g00 = ws[24] * ws[24] + ws[25] * ws[25] + ws[26] * ws[26]
        if g00 > 0.0:
            ig = 1.0 / g00
            for r in range(12):
                for c in range(12):
                    hess[r, c] -= ws[r] * ws[c] * ig
    elif nf == 2:
        g00 = ws[24] * ws[24] + ws[25] * ws[25] + ws[26] * ws[26]
        g11 = ws[27] * ws[27] + ws[28] * ws[28] + ws[29] * ws[29]
        g01 = ws[24] * ws[27] + ws[25] * ws[28] + ws[26] * ws[29]
        det = g00 * g11 - g01 * g01
        if det > 1e-12 * g00 * g11:
            i00 = g11 / det
            i11 = g00 / det
            i01 = -g01 / det
            for r in range(12):
                ar = ws[r]
                br = ws[12 + r]
                for c in range(12):
                    ac = ws[c]
                    bc = ws[12 + c]
                    hess[r, c] -= ar * (i00 * ac + i01 * bc) + br * (i01 * ac + i11 * bc)
        elif g00 > 0.0:  # (nearly) parallel edges: the point–edge Hessian (s interior only)
            ig = 1.0 / g00
            for r in range(12):
                for c in range(12):
                    hess[r, c] -= ws[r] * ws[c] * ig
    for r in range(12):
        for c in range(12):
            hess[r, c] = (hess[r, c] - grad[r] * grad[c]) * inv
    return dd, s, t


@njit(**OPT_CONTACT)
def _edge_boxes(x_start, x_end, radius, margin, box):
    """box (E, 6): each edge's axis-aligned box over its positions at the start and the end of the motion, grown
    by its radius and half the margin (two boxes overlap iff the grown-by-the-whole-margin test would pass)."""
    for j in range(box.shape[0]):
        g = edge_radius(radius, j) + 0.5 * margin
        for a in range(3):
            lo = min(x_start[j, a], x_start[j + 1, a], x_end[j, a], x_end[j + 1, a])
            hi = max(x_start[j, a], x_start[j + 1, a], x_end[j, a], x_end[j + 1, a])
            box[j, a] = lo - g
            box[j, 3 + a] = hi + g


@njit(inline="always", **OPT_CONTACT)
def _boxes_overlap(box, i, j):
    return (box[i, 0] <= box[j, 3] and box[j, 0] <= box[i, 3] and box[i, 1] <= box[j, 4] and box[j, 1] <= box[i, 4]
            and box[i, 2] <= box[j, 5] and box[j, 2] <= box[i, 5])


@njit(**OPT_CONTACT)
def find_candidates(ep, pairs, x_start, x_end, radius, margin):
    """Candidates among the allowed ``pairs`` (P, 2) for a motion from ``x_start`` to ``x_end``: the indices into
    ``pairs`` of the pairs whose swept boxes overlap, into ``ep.cand`` (P,); ``ep.count[0]`` their count."""
    box, cand, ncand = ep.box, ep.cand, ep.count
    _edge_boxes(x_start, x_end, radius, margin, box)
    n = 0
    for c in range(pairs.shape[0]):
        if _boxes_overlap(box, pairs[c, 0], pairs[c, 1]):
            cand[n] = c
            n += 1
    ncand[0] = n
    return n


@njit(**OPT_CONTACT)
def add_candidates(ep, pairs, x_start, x_end, radius, margin):
    """Add to the candidate list the allowed pairs whose boxes over the motion ``x_start`` → ``x_end`` overlap and
    that are not in it yet (the list stays sorted). Returns (whether any pair was added, the smallest gap [m] at
    ``x_end`` of the pairs added (+inf when none was)): a pair added at a gap of δ or more exerts no force there."""
    box, cand, ncand = ep.box, ep.cand, ep.count
    _edge_boxes(x_start, x_end, radius, margin, box)
    n0 = ncand[0]
    added = False
    smallest = np.inf
    k = 0
    n = n0
    for c in range(pairs.shape[0]):
        while k < n0 and cand[k] < c:
            k += 1
        if k < n0 and cand[k] == c:
            continue
        if _boxes_overlap(box, pairs[c, 0], pairs[c, 1]):
            cand[n] = c
            n += 1
            added = True
            smallest = min(smallest, _gap(x_end, radius, pairs[c, 0], pairs[c, 1]))
    if added:  # insertion sort of the appended tail into the sorted head
        for m in range(n0, n):
            v = cand[m]
            p = m - 1
            while p >= 0 and cand[p] > v:
                cand[p + 1] = cand[p]
                p -= 1
            cand[p + 1] = v
    ncand[0] = n
    return added, smallest


@njit(inline="always", **OPT_CONTACT)
def _dof(dpn, k, a):
    """DOF index of coordinate a of node k: 3-D 4k + a; planar 2k (x), 2k + 1 (z), −1 for y (not a DOF)."""
    if dpn == 4:
        return 4 * k + a
    if a == 1:
        return -1
    return 2 * k + (0 if a == 0 else 1)


@njit(inline="always", **OPT_CONTACT)
def _slot(cp, d):
    """Index of DOF d in the coupling list ``cp``, appended if new."""
    s = cp.slot[d]
    if s < 0:
        s = cp.count[0]
        cp.slot[d] = s
        cp.dof[s] = d
        cp.count[0] = s + 1
    return s


@njit(inline="always", **OPT_CONTACT)
def _segments_gap(a, b, p, q, rs):
    """(gap [m], s, t, distance [m]) of segments (a, b) and (p, q) whose radii sum to ``rs``: s, t locate the
    closest points on each (0 at a / p, 1 at b / q), the distance is between them."""
    s, t = closest_seg_seg(a, b, p, q)
    u = vsub(vlerp(a, b, s), vlerp(p, q, t))
    dd = math.sqrt(vdot(u, u))
    return dd - rs, s, t, dd


@njit(inline="always", **OPT_CONTACT)
def _gap(x, radius, i, j):
    """Gap [m] of edges i and j at node positions x."""
    return _segments_gap(row3(x, i), row3(x, i + 1), row3(x, j), row3(x, j + 1),
                         edge_radius(radius, i) + edge_radius(radius, j))[0]


pair_gap = _gap  # the public name (sim.kernels.probe)


@njit(inline="always", **OPT_CONTACT)
def _gap_bound(x, radius, i, j):
    """A lower bound of the gap [m] of edges i and j (≤ :func:`_gap`) from each edge's bounding sphere (centre
    the midpoint, radius half the length): a few operations, where the exact gap needs the closest points. Pairs
    along a rod within the broad-phase margin but far apart fail the contact tests with it alone."""
    c0 = 0.5 * (x[i, 0] + x[i + 1, 0]) - 0.5 * (x[j, 0] + x[j + 1, 0])
    c1 = 0.5 * (x[i, 1] + x[i + 1, 1]) - 0.5 * (x[j, 1] + x[j + 1, 1])
    c2 = 0.5 * (x[i, 2] + x[i + 1, 2]) - 0.5 * (x[j, 2] + x[j + 1, 2])
    ei = math.sqrt((x[i + 1, 0] - x[i, 0]) ** 2 + (x[i + 1, 1] - x[i, 1]) ** 2 + (x[i + 1, 2] - x[i, 2]) ** 2)
    ej = math.sqrt((x[j + 1, 0] - x[j, 0]) ** 2 + (x[j + 1, 1] - x[j, 1]) ** 2 + (x[j + 1, 2] - x[j, 2]) ** 2)
    slack = 1e-12 * (ei + ej + abs(x[i, 0]) + abs(x[i, 1]) + abs(x[i, 2]))  # rounding: never above the exact gap
    return math.sqrt(c0 * c0 + c1 * c1 + c2 * c2) - 0.5 * (ei + ej) - edge_radius(radius, i) - edge_radius(radius, j) \
        - slack


@njit(inline="always", **OPT_CONTACT)
def _is_candidate(ep, c):
    """Whether allowed pair ``c`` is in the (sorted) candidate list of ``ep``."""
    lo = 0
    hi = ep.count[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if ep.cand[mid] < c:
            lo = mid + 1
        else:
            hi = mid
    return lo < ep.count[0] and ep.cand[lo] == c


# The terms a pair carries (docs/physics.md §4.8, "One crossing, one contact"): each rod's centre line is counted as
# its edges (+1) less its interior nodes (−1), so every point of it counts once; pair (i, j) carries its edges'
# term and the terms of the start nodes it owns.
TERM_EDGE_EDGE = 0   # edge i vs edge j, +E
TERM_NODE_EDGE = 1   # node i (start of edge i, shared with edge i − 1) vs edge j, −E
TERM_EDGE_NODE = 2   # edge i vs node j (shared with edge j − 1), −E
TERM_NODE_NODE = 3   # node i vs node j, +E


@njit(inline="always", **OPT_CONTACT)
def _terms(ep, links, c):
    """Bit mask of the terms pair ``c`` carries: always its edges' (bit 0); node i's (bit 1) when the pair with
    edge i − 1 is a candidate too, node j's (bit 2) likewise with edge j − 1, both nodes' (bit 3) when the pairs
    with edge i − 1, with edge j − 1 and with both are."""
    m = 1
    a = links[c, 0] >= 0 and _is_candidate(ep, links[c, 0])
    b = links[c, 1] >= 0 and _is_candidate(ep, links[c, 1])
    if a:
        m |= 2
    if b:
        m |= 4
    if a and b and links[c, 2] >= 0 and _is_candidate(ep, links[c, 2]):
        m |= 8
    return m


@njit(inline="always", **OPT_CONTACT)
def _term_geometry(x, radius, i, j, kind):
    """The segments (a, b), (p, q) of a term of pair (i, j) — a node is a segment of zero length, so the
    closest-point rule and :func:`seg_seg_derivs` give its weights with zero on the node not in it — their radii
    sum [m] (at a node the thinner of its two edges', so the edges' capsules' union keeps the thicker one) and the
    term's sign."""
    a = row3(x, i)
    p = row3(x, j)
    b = a
    q = p
    ra = edge_radius(radius, i)
    rb = edge_radius(radius, j)
    sign = 1.0
    if kind == TERM_EDGE_EDGE or kind == TERM_EDGE_NODE:
        b = row3(x, i + 1)
    else:
        ra = min(ra, edge_radius(radius, i - 1))
        sign = -sign
    if kind == TERM_EDGE_EDGE or kind == TERM_NODE_EDGE:
        q = row3(x, j + 1)
    else:
        rb = min(rb, edge_radius(radius, j - 1))
        sign = -sign
    return a, b, p, q, ra + rb, sign


@njit(inline="always", **OPT_CONTACT)
def _term_gap(x, radius, i, j, kind):
    """(gap [m], s, t, sign) of a term of pair (i, j) at node positions x."""
    a, b, p, q, rs, sign = _term_geometry(x, radius, i, j, kind)
    g, s, t, _ = _segments_gap(a, b, p, q, rs)
    return g, s, t, sign


@njit(**OPT_CONTACT)
def reset_coupling(cp):
    """Empty the coupling list ``cp`` (before a Jacobian assembly)."""
    K = cp.count[0]
    for s in range(K):
        cp.slot[cp.dof[s]] = -1
        for c in range(K):
            cp.M[s, c] = 0.0
    cp.count[0] = 0


@njit(inline="always", **OPT_CONTACT)
def _pair_slip(x, x_prev, dt, nodes, cw, nhat, mu, nu, lam):
    """Friction of a pair in touch (lagged n̂, s, t): (γ, γ', |v_t|, t̂) of the contact points' relative tangential
    velocity ``v = Σ c_k (x_k − x_prev_k)/dt``; γ = 0 (no friction) for μ = 0, no normal force or no slip."""
    gam = 0.0
    dgam = 0.0
    vtn = 0.0
    tv0 = 0.0
    tv1 = 0.0
    tv2 = 0.0
    if mu > 0.0 and lam > 0.0:
        v0 = 0.0
        v1 = 0.0
        v2 = 0.0
        for q in range(4):
            nd = nodes[q]
            v0 += cw[q] * (x[nd, 0] - x_prev[nd, 0])
            v1 += cw[q] * (x[nd, 1] - x_prev[nd, 1])
            v2 += cw[q] * (x[nd, 2] - x_prev[nd, 2])
        v0 /= dt
        v1 /= dt
        v2 /= dt
        vn = v0 * nhat[0] + v1 * nhat[1] + v2 * nhat[2]
        v0 -= vn * nhat[0]
        v1 -= vn * nhat[1]
        v2 -= vn * nhat[2]
        vtn = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if vtn > 1e-15:
            tv0 = v0 / vtn
            tv1 = v1 / vtn
            tv2 = v2 / vtn
            gam, dgam = coulomb_factor(vtn, nu)
    return gam, dgam, vtn, (tv0, tv1, tv2)


@njit(inline="always", **OPT_CONTACT)
def _add_term(i, j, a, b, p, q, rs, sign, ep, law, x, x_prev, dt, dpn, fixed, system, sym, with_jac):
    """Add one term of pair (i, j) — segments (a, b) and (p, q) on the nodes (i, i + 1, j, j + 1), radii sum
    ``rs``, sign ±1 — to the residual and (``with_jac``) the Jacobian; returns its energy [J] (0 out of reach)."""
    k, delta, mu, nu = law.contact_k, law.contact_delta, law.friction, law.friction_nu
    g12, H12, nhat, ws = ep.g12, ep.H12, ep.nhat, ep.ws
    f, ab, cp = system.f, system.ab, system.coupling
    kl = ab.shape[1] // 2
    dd, s, t = seg_seg_derivs(a, b, p, q, g12, H12, nhat, ws)
    gap = dd - rs
    if gap >= delta:
        return 0.0
    E, dE, d2E = imc_energy(gap, k, delta)
    cw = (1.0 - s, s, -(1.0 - t), -t)
    nodes = (i, i + 1, j, j + 1)
    lam = -dE
    gam, dgam, vtn, tv = _pair_slip(x, x_prev, dt, nodes, cw, nhat, mu, nu, lam)
    cf = mu * lam * gam
    for r in range(4):
        for c in range(3):
            d = _dof(dpn, nodes[r], c)
            if d >= 0:
                f[d] += sign * (dE * g12[3 * r + c] + cf * cw[r] * tv[c])
    if not with_jac:
        return sign * E
    # contact Hessian E'' ∇Δ∇Δᵀ + E' ∇²Δ, then friction's consistent part
    for r in range(12):
        for c in range(12):
            H12[r, c] = d2E * g12[r] * g12[c] + dE * H12[r, c]
    if gam > 0.0:
        a1 = mu * lam / dt
        for r in range(3):
            for c in range(3):
                blk = friction_tangent_entry(a1, dgam, gam, vtn, tv, nhat, mu, d2E, r, c)
                for u in range(4):
                    for v in range(4):
                        H12[3 * u + r, 3 * v + c] += blk * cw[u] * cw[v]
    for u in range(4):
        if cw[u] == 0.0:
            continue  # the node a node term leaves out
        for r in range(3):
            row = _dof(dpn, nodes[u], r)
            if row < 0 or fixed[row]:
                continue
            for v in range(4):
                if cw[v] == 0.0:
                    continue
                same_edge = (u < 2) == (v < 2)
                for c in range(3):
                    col = _dof(dpn, nodes[v], c)
                    if col < 0 or fixed[col]:
                        continue
                    val = sign * H12[3 * u + r, 3 * v + c]
                    if same_edge:
                        if sym and col < row:
                            continue
                        ab[row, kl + col - row] += val
                    else:
                        cp.M[_slot(cp, row), _slot(cp, col)] += val
    return sign * E


@njit(**OPT_CONTACT)
def add_forces(ep, pairs, links, law, x, x_prev, dt, dpn, fixed, radius, system, sym, with_jac):
    """Add the IMC energy and friction of the candidate pairs at node positions ``x`` (N, 3) to the residual
    ``system.f`` (DOFs) and, with ``with_jac``, the Jacobian: blocks of an edge with itself into the padded band
    ``system.ab`` (upper half only with ``sym``), blocks between the two edges into the coupling list
    ``system.coupling`` (entries on constrained DOFs dropped: those rows and columns are identity). ``system``: a
    Workspace (sim.kernels.workspace). Each pair adds its terms (:func:`_terms`; ``links``: :func:`pair_links`).
    Velocities (x − x_prev)/dt. Returns the energy [J]."""
    delta = law.contact_delta
    cand, ncand = ep.cand, ep.count
    energy = 0.0
    for m in range(ncand[0]):
        c = cand[m]
        i = pairs[c, 0]
        j = pairs[c, 1]
        # every term's gap is at least the edges' (a node is part of its edge): most candidates end here
        if _gap_bound(x, radius, i, j) >= delta or _gap(x, radius, i, j) >= delta:
            continue
        energy += _add_term(i, j, row3(x, i), row3(x, i + 1), row3(x, j), row3(x, j + 1),
                            edge_radius(radius, i) + edge_radius(radius, j), 1.0, ep, law, x, x_prev, dt, dpn, fixed,
                            system, sym, with_jac)
        mask = _terms(ep, links, c)
        for kind in range(1, 4):
            if not mask & (1 << kind):
                continue
            a, b, p, q, rs, sign = _term_geometry(x, radius, i, j, kind)
            if _segments_gap(a, b, p, q, rs)[0] < delta:  # derivatives only in reach
                energy += _add_term(i, j, a, b, p, q, rs, sign, ep, law, x, x_prev, dt, dpn, fixed, system, sym,
                                    with_jac)
    return energy


@njit(**OPT_CONTACT)
def smallest_gap(ep, pairs, x, radius):
    """Smallest gap [m] over the candidate pairs at positions ``x``, or +inf without candidates."""
    cand = ep.cand
    best = np.inf
    for m in range(ep.count[0]):
        i = pairs[cand[m], 0]
        j = pairs[cand[m], 1]
        if _gap_bound(x, radius, i, j) >= best:
            continue
        gap = _gap(x, radius, i, j)
        if gap < best:
            best = gap
    return best


@njit(**OPT_CONTACT)
def pair_energy(ep, pairs, links, law, x, radius):
    """IMC energy [J] of the candidate pairs' terms (:func:`_terms`) at positions ``x`` (no friction, no
    derivatives)."""
    k, delta, cand = law.contact_k, law.contact_delta, ep.cand
    energy = 0.0
    for m in range(ep.count[0]):
        c = cand[m]
        i = pairs[c, 0]
        j = pairs[c, 1]
        if _gap_bound(x, radius, i, j) >= delta:
            continue
        gap = _gap(x, radius, i, j)
        if gap >= delta:
            continue
        energy += imc_energy(gap, k, delta)[0]
        mask = _terms(ep, links, c)
        for kind in range(1, 4):
            if mask & (1 << kind):
                g, _, _, sign = _term_gap(x, radius, i, j, kind)
                if g < delta:
                    energy += sign * imc_energy(g, k, delta)[0]
    return energy


@njit(inline="always", **OPT_CONTACT)
def _term_normal(ep, a, b, p, q, s, t, dd):
    """Unit normal of a term (segments (a, b), (p, q), closest-point parameters s, t, centre-line distance ``dd``),
    from the (p, q) point to the (a, b) point, as the assembly uses it; also left in ``ep.nhat``."""
    nhat = ep.nhat
    u = vsub(vlerp(a, b, s), vlerp(p, q, t))
    e1 = vsub(b, a)
    e2 = vsub(q, p)
    if dd > 1e-12 * max(math.sqrt(vdot(e1, e1)), math.sqrt(vdot(e2, e2)), 1e-300):  # as seg_seg_derivs
        inv = 1.0 / dd
        for c in range(3):
            nhat[c] = u[c] * inv
    else:  # touching centre lines: the normal the assembly uses there
        seg_seg_derivs(a, b, p, q, ep.g12, ep.H12, nhat, ep.ws)
    return nhat[0], nhat[1], nhat[2]


@njit(**OPT_CONTACT)
def pair_rows(e, ep, pairs, links, law, x, x_prev, dt, radius, rows):
    """The candidate pairs at the state kept, in one pass: returns their IMC energy [J] (no friction; each pair's
    terms, :func:`_terms`) and smallest gap [m] (+inf without candidates), and appends env ``e``'s pairs in touch
    (gap < δ) to its contact rows after the ``rows.count[e]`` obstacle rows of ``rows`` (a
    :class:`sim.kernels.data.ContactReport`), up to its capacity C: two rows per pair, one for each edge, each the
    force *on* that edge. Row of edge i against edge j: edge i, obstacle −1, partner j, rod point on i's centre
    line, "obstacle point" the closest point on j's surface, the pair's net normal force on i (over its terms: the
    unit normal, from j to i for a pair alone, and its size λ [N]; λ = −E'(g) for a pair alone), its net friction
    force on i [N], the gap g [m] of the two edges; edge j's row mirrors it (normal and friction reversed), so each
    pair's two rows sum to zero. A pair whose terms cancel (a crossing on a node, carried by its neighbour) is not
    listed. The obstacle rows' partner entries are set to −1; pairs in touch beyond the capacity add two to
    ``rows.dropped[e]`` each. Velocities (x − x_prev)/dt."""
    k, delta, mu, nu = law.contact_k, law.contact_delta, law.friction, law.friction_nu
    cand, ncand = ep.cand, ep.count
    cap = rows.gap.shape[1]
    rc = rows.count[e]
    for r in range(rc):
        rows.partner[e, r] = -1
    energy = 0.0
    smallest = np.inf
    for m in range(ncand[0]):
        c = cand[m]
        i = pairs[c, 0]
        j = pairs[c, 1]
        bound = _gap_bound(x, radius, i, j)
        if bound >= delta and bound >= smallest:  # neither in touch nor the deepest
            continue
        ri = edge_radius(radius, i)
        rj = edge_radius(radius, j)
        a = row3(x, i)
        b = row3(x, i + 1)
        p = row3(x, j)
        q = row3(x, j + 1)
        gap, s, t, dd = _segments_gap(a, b, p, q, ri + rj)  # as _gap
        smallest = min(smallest, gap)
        if gap >= delta:
            continue
        pi = vlerp(a, b, s)
        pj = vlerp(p, q, t)
        # the pair's net force on edge i over its terms: normal part fn, friction part ff
        fn0 = 0.0
        fn1 = 0.0
        fn2 = 0.0
        ff0 = 0.0
        ff1 = 0.0
        ff2 = 0.0
        lam_pair = 0.0
        mask = _terms(ep, links, c)
        for kind in range(4):
            if not mask & (1 << kind):
                continue
            if kind == TERM_EDGE_EDGE:
                ta, tb, tp, tq, sign = a, b, p, q, 1.0
                ts, tt, tdd, tgap = s, t, dd, gap
            else:
                ta, tb, tp, tq, rs, sign = _term_geometry(x, radius, i, j, kind)
                tgap, ts, tt, tdd = _segments_gap(ta, tb, tp, tq, rs)
                if tgap >= delta:
                    continue
            E, dE, _ = imc_energy(tgap, k, delta)
            energy += sign * E
            n0, n1, n2 = _term_normal(ep, ta, tb, tp, tq, ts, tt, tdd)
            lam = -dE
            if kind == TERM_EDGE_EDGE:
                lam_pair = lam
            gam, _, _, tv = _pair_slip(x, x_prev, dt, (i, i + 1, j, j + 1), (1.0 - ts, ts, -(1.0 - tt), -tt),
                                       ep.nhat, mu, nu, lam)
            cf = sign * mu * lam * gam  # friction on edge i is −cf t̂ (t̂: i's slip relative to j)
            fn0 += sign * lam * n0
            fn1 += sign * lam * n1
            fn2 += sign * lam * n2
            ff0 -= cf * tv[0]
            ff1 -= cf * tv[1]
            ff2 -= cf * tv[2]
        size = math.sqrt(fn0 * fn0 + fn1 * fn1 + fn2 * fn2)
        if size <= 1e-9 * lam_pair:
            continue  # the terms cancel: the crossing is its neighbour's
        if rc + 2 > cap:
            rows.dropped[e] += 2  # the two rows' forces cancel: the total force needs neither
            continue
        en = (fn0 / size, fn1 / size, fn2 / size)
        ee_n = _term_normal(ep, a, b, p, q, s, t, dd)
        for side in range(2):
            sg = 1.0 if side == 0 else -1.0
            rows.edge[e, rc] = i if side == 0 else j
            rows.obstacle[e, rc] = -1
            rows.partner[e, rc] = j if side == 0 else i
            for cc in range(3):
                rows.rod_point[e, rc, cc] = pi[cc] if side == 0 else pj[cc]
                rows.obstacle_point[e, rc, cc] = pj[cc] + rj * ee_n[cc] if side == 0 else pi[cc] - ri * ee_n[cc]
                rows.normal[e, rc, cc] = sg * en[cc]
            rows.friction_force[e, rc, 0] = sg * ff0
            rows.friction_force[e, rc, 1] = sg * ff1
            rows.friction_force[e, rc, 2] = sg * ff2
            rows.normal_force[e, rc] = size
            rows.gap[e, rc] = gap
            rc += 1
    rows.count[e] = rc
    return energy, smallest


@njit(inline="always", **OPT_CONTACT)
def _pair_distance(x, dxp, tt, i, j):
    """Centre-line distance of edges i, j at positions x + tt·dxp."""
    a = (x[i, 0] + tt * dxp[i, 0], x[i, 1] + tt * dxp[i, 1], x[i, 2] + tt * dxp[i, 2])
    b = (x[i + 1, 0] + tt * dxp[i + 1, 0], x[i + 1, 1] + tt * dxp[i + 1, 1], x[i + 1, 2] + tt * dxp[i + 1, 2])
    p = (x[j, 0] + tt * dxp[j, 0], x[j, 1] + tt * dxp[j, 1], x[j, 2] + tt * dxp[j, 2])
    q = (x[j + 1, 0] + tt * dxp[j + 1, 0], x[j + 1, 1] + tt * dxp[j + 1, 1], x[j + 1, 2] + tt * dxp[j + 1, 2])
    return _segments_gap(a, b, p, q, 0.0)[3]


@njit(inline="always", **OPT_CONTACT)
def _gap_floor(g, delta, rs):
    """The lowest gap [m] one update may bring a pair at gap ``g`` to: min(g, 0) − δ, but never letting the centre
    lines meet (radii sum ``rs``)."""
    floor = min(g, 0.0) - delta
    if floor < -rs:
        floor = -rs * (1.0 - 1e-3)
    return floor


@njit(**OPT_CONTACT)
def update_fraction(ep, pairs, x, dxp, radius, delta):
    """Largest fraction τ ∈ (0, 1] of the Newton update ``dxp`` ((N, 3) node displacements from positions ``x``)
    along which no candidate pair's gap falls below min(g0, 0) − δ (g0 its gap at τ = 0): one update can neither
    carry an edge through another nor push a touching pair more than δ deeper. Conservative advancement: the
    distance of two segments is Lipschitz in τ with the sum D of the two edges' largest node displacements."""
    cand = ep.cand
    tmax = 1.0
    for m in range(ep.count[0]):
        i = pairs[cand[m], 0]
        j = pairs[cand[m], 1]
        Di = max(math.sqrt(dxp[i, 0] ** 2 + dxp[i, 1] ** 2 + dxp[i, 2] ** 2),
                 math.sqrt(dxp[i + 1, 0] ** 2 + dxp[i + 1, 1] ** 2 + dxp[i + 1, 2] ** 2))
        Dj = max(math.sqrt(dxp[j, 0] ** 2 + dxp[j, 1] ** 2 + dxp[j, 2] ** 2),
                 math.sqrt(dxp[j + 1, 0] ** 2 + dxp[j + 1, 1] ** 2 + dxp[j + 1, 2] ** 2))
        D = Di + Dj
        if D <= 0.0:
            continue
        rs = edge_radius(radius, i) + edge_radius(radius, j)
        gb = _gap_bound(x, radius, i, j)
        if gb >= 0.0 and gb - D * tmax >= _gap_floor(0.0, delta, rs):  # g ≥ gb ≥ 0: g's floor, and g passes too
            continue
        g = _gap(x, radius, i, j)
        floor = _gap_floor(g, delta, rs)
        if g - D * tmax >= floor:
            continue
        tt = 0.0
        for _ in range(256):
            step = (g - floor) / D
            if step < 1e-3 * delta / D:
                break
            tt += step
            if tt >= tmax:
                break
            g = _pair_distance(x, dxp, tt, i, j) - rs
        if tt < tmax:
            tmax = tt
    return max(tmax, 1e-3)


# ------------------------------------------------------------------------------------- allocation
@njit(**OPT_ALLOC)
def alloc(N, P):
    """One thread's :class:`EdgePairContact` for a rod of N nodes with P allowed pairs (empty arrays when P = 0)."""
    return EdgePairContact(np.zeros(P, np.int64), np.zeros(1, np.int64), np.empty((N - 1 if P > 0 else 0, 6)),
                           np.empty(12), np.empty((12, 12)), np.empty(3), np.empty(32))


@njit(**OPT_ALLOC)
def alloc_coupling(n, K, kl):
    """An empty :class:`Coupling` over n DOFs with room for K listed DOFs (K = 0 without edge pairs)."""
    return Coupling(np.full(n if K > 0 else 0, -1, np.int64), np.zeros(K, np.int64), np.zeros(1, np.int64),
                    np.zeros((K, K)), np.empty((K, n + kl)), np.empty((K, K)), np.empty(K), np.empty(K, np.int64))


# ------------------------------------------------------------------------------------- the contact protocol
# The same functions, with the same arguments, as sim.contact.obstacles (see sim.contact.stages).
@njit(inline="always", **OPT_CONTACT)
def present(prm):
    """Whether edges of the scene's rods may touch each other."""
    return prm.rod_pairs


@njit(inline="always", **OPT_CONTACT)
def candidates(e, ep):
    """The candidate count (``ep`` is the thread's, for the env it steps)."""
    return ep.count[0]


@njit(inline="always", **OPT_CONTACT)
def friction_acts(prm):
    """Whether friction can act between edges (the [contact] μ > 0)."""
    return prm.friction > 0


@njit(inline="always", **OPT_CONTACT)
def broadphase(e, prm, rod, ep, pos0, pos):
    """Candidates over the motion pos0 → pos."""
    find_candidates(ep, rod.pairs, pos0, pos, rod.edge_radius, prm.contact_margin)


@njit(inline="always", **OPT_CONTACT)
def refresh(e, prm, rod, ep, pos0, pos):
    """Candidates over the motion pos0 → pos added to the list: (whether pairs were added, whether the (sub)step must
    be solved again: so an added pair is within reach of the potential, gap < δ)."""
    added, added_gap = add_candidates(ep, rod.pairs, pos0, pos, rod.edge_radius, prm.contact_margin)
    return added, added_gap < prm.contact_delta


@njit(inline="always", **OPT_CONTACT)
def penetration(e, prm, rod, ep, pos):
    """Deepest penetration [m] (≥ 0) of the candidate pairs at ``pos``."""
    return max(0.0, -smallest_gap(ep, rod.pairs, pos, rod.edge_radius))


@njit(inline="always", **OPT_CONTACT)
def step_limit(e, prm, rod, ep, pos, dpos):
    """Largest fraction of the node update ``dpos`` that carries no edge through another (:func:`update_fraction`)."""
    return update_fraction(ep, rod.pairs, pos, dpos, rod.edge_radius, prm.contact_delta)


@njit(inline="always", **OPT_CONTACT)
def accumulate(e, prm, rod, ep, w, h, with_jac, sym):
    """Add the pairs' residual into ``w.f`` and (``with_jac``) their Jacobian into the band ``w.ab`` and the coupling
    list ``w.coupling`` (emptied first) at the nodes w.pos, velocities from w.pos0 over h; returns the energy [J]."""
    if with_jac:
        reset_coupling(w.coupling)
    return add_forces(ep, rod.pairs, rod.pair_links, prm, w.pos, w.pos0, h, 2 if prm.planar else 4, rod.fixed, rod.edge_radius, w,
                      sym, with_jac)


@njit(inline="always", **OPT_CONTACT)
def energy(e, prm, rod, ep, pos, pos0, h):
    """IMC energy [J] of the candidate pairs at ``pos``."""
    return pair_energy(ep, rod.pairs, rod.pair_links, prm, pos, rod.edge_radius)


@njit(inline="always", **OPT_CONTACT)
def report(e, prm, rod, ep, pos, pos0, rows):
    """The pairs in touch at the state kept (``pos``; velocities from pos0 over the step) over a fresh candidate list:
    their rows appended after the obstacles' in ``rows``, the max penetration raised to theirs; returns the
    energy [J]."""
    find_candidates(ep, rod.pairs, pos, pos, rod.edge_radius, prm.contact_margin)
    ec, smallest = pair_rows(e, ep, rod.pairs, rod.pair_links, prm, pos, pos0, prm.dt, rod.edge_radius, rows)
    rows.max_penetration[e] = max(rows.max_penetration[e], max(0.0, -smallest))
    return ec
