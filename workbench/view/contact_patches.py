"""Contact patches: the contact rows of one frame grouped where the rod touches something, for the force labels.

A rod resting on a floor or pressed by an obstacle touches along several edges at once; one label per row buries the
rod in overlapping numbers, some of them the regularised law's noise (5e-05 N beside 187 N). Rows that touch the same
thing (an obstacle, or another stretch of rod) and whose rod points lie within ``reach`` of each other (single
linkage: a chain of neighbouring rows is one patch) form one patch; its label is the patch's total force, and a patch
carrying under ``LABEL_FRACTION`` of the largest patch's gets none. An edge pair in touch has two rows, the equal and
opposite forces on its two edges; its patch counts one side (the force on the lower-numbered edge), so a crossing
reads the force the rods press each other with, not their sum (zero). Pure numpy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LABEL_FRACTION = 0.01  # patches below this fraction of the largest patch's force get no label


@dataclass(frozen=True)
class Patch:
    """One contact patch: its rows (indices into the frame's contact arrays), total force (3,) [N] and the row
    carrying the most (where its label goes)."""

    rows: np.ndarray
    force: np.ndarray
    main_row: int

    @property
    def magnitude(self) -> float:
        return float(np.linalg.norm(self.force))


def patches(points: np.ndarray, forces: np.ndarray, reach: float, obstacle=None, edge=None,
            partner_edge=None) -> list[Patch]:
    """The contact rows (rod points (K, 3) [m], forces (K, 3) [N]) grouped into patches of rows within ``reach``
    [m] of a neighbour, largest total force first. With the rows' ``obstacle`` (K,) (−1 on an edge-pair row),
    ``edge`` and ``partner_edge`` (K,) (``sim.StepStats``), rows touching different things never share a patch and
    a pair counts once; without them (a recording) the grouping is by distance alone."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    f = np.asarray(forces, np.float64).reshape(-1, 3)
    k = len(p)
    if k == 0:
        return []
    touched = np.zeros(k, np.int64)
    counted = np.ones(k, bool)
    if obstacle is not None and edge is not None and partner_edge is not None:
        touched = np.asarray(obstacle, np.int64).reshape(k)
        counted = (touched >= 0) | (np.asarray(edge).reshape(k) < np.asarray(partner_edge).reshape(k))
    parent = np.arange(k)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)
    near = (d <= reach) & (touched[:, None] == touched[None, :])
    for i, j in zip(*np.nonzero(np.triu(near, 1))):
        a, b = root(int(i)), root(int(j))
        if a != b:
            parent[max(a, b)] = min(a, b)
    roots = np.array([root(i) for i in range(k)])
    mag = np.where(counted, np.linalg.norm(f, axis=1), -1.0)
    out = []
    for r in np.unique(roots):
        rows = np.nonzero(roots == r)[0]
        out.append(Patch(rows=rows, force=f[rows[counted[rows]]].sum(axis=0),
                         main_row=int(rows[np.argmax(mag[rows])])))
    return sorted(out, key=lambda q: -q.magnitude)


def labelled(found: list[Patch], limit: int) -> list[Patch]:
    """The patches that get a label: at most ``limit``, largest first, none under ``LABEL_FRACTION`` of the
    largest (and none carrying nothing)."""
    if not found:
        return []
    top = found[0].magnitude
    return [q for q in found[:limit] if q.magnitude > 0.0 and q.magnitude >= LABEL_FRACTION * top]


def reach_of(node_pos: np.ndarray) -> float:
    """The linking distance of a rod's patches: one and a half of its median edge length (neighbouring edges'
    contact points are about an edge apart; the median leaves out a long joint edge between two rods)."""
    x = np.asarray(node_pos, np.float64)
    if len(x) < 2:
        return 0.0
    return 1.5 * float(np.median(np.linalg.norm(np.diff(x, axis=0), axis=1)))
