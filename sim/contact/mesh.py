"""Triangle meshes for rigid obstacles: loading/validation (trimesh) and a static AABB tree (BVH).

The BVH is built once per mesh, in the mesh's local frame (after ``scale``), with a median split on the
longest centroid axis and at most ``LEAF_SIZE`` triangles per leaf. Queries are numba kernels: the cost
grows with the triangles near the query box, not with the mesh size.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numba import njit

__all__ = ["MeshError", "load_mesh_triangles", "build_bvh", "bvh_any_overlap", "cylinder_triangles", "LEAF_SIZE"]

LEAF_SIZE = 4

_CACHE: dict[tuple, np.ndarray] = {}


class MeshError(ValueError):
    """A mesh file is unreadable or unusable (the message names the file)."""


def load_mesh_triangles(path: str | os.PathLike, scale: float | tuple = 1.0) -> np.ndarray:
    """Read any mesh trimesh can read (STL, OBJ, PLY, GLB, ...) -> triangles (T, 3, 3) float64 [m].

    ``scale`` is a float or 3 per-axis factors applied in the mesh frame. Degenerate (zero-area)
    triangles are dropped. Raises :class:`MeshError` naming the file when the file is missing or
    unreadable, has no triangles, non-finite vertices, or only zero-area triangles. Results are cached
    per (path, mtime, scale).
    """
    p = Path(path)
    sc = np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)).copy()
    try:
        st = p.stat()
    except OSError:
        raise MeshError(f"{p}: mesh file not found") from None
    key = (str(p.resolve()), st.st_mtime_ns, st.st_size, tuple(sc))
    if key in _CACHE:
        return _CACHE[key]
    import trimesh  # lazy: only scenes with meshes pay the import

    try:
        loaded = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds
        raise MeshError(f"{p}: cannot read mesh: {type(exc).__name__}: {exc}") from None
    if isinstance(loaded, trimesh.Scene):  # pragma: no cover - force="mesh" usually concatenates
        geoms = list(loaded.geometry.values())
        if not geoms:
            raise MeshError(f"{p}: mesh file holds no geometry")
        loaded = trimesh.util.concatenate(geoms)
    v = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    f = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))), dtype=np.int64)
    if f.ndim != 2 or f.shape[0] == 0 or v.shape[0] == 0:
        raise MeshError(f"{p}: mesh has no triangles")
    if f.shape[1] != 3:
        raise MeshError(f"{p}: expected triangle faces, got faces of shape {f.shape}")
    if not np.all(np.isfinite(v)):
        raise MeshError(f"{p}: mesh has non-finite (NaN/inf) vertex coordinates")
    if f.min() < 0 or f.max() >= v.shape[0]:
        raise MeshError(f"{p}: face indices out of range")
    tri = v[f] * sc[None, None, :]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    ext = float(np.max(np.ptp(tri.reshape(-1, 3), axis=0)))
    keep = area2 > 1e-14 * max(ext, 1e-300) ** 2
    if not np.any(keep):
        raise MeshError(f"{p}: all {tri.shape[0]} triangles have zero area")
    tri = np.ascontiguousarray(tri[keep])
    tri.setflags(write=False)
    _CACHE[key] = tri
    return tri


@njit(cache=True)
def _build(tri, leaf_size):
    T = tri.shape[0]
    tlo = np.empty((T, 3))
    thi = np.empty((T, 3))
    cen = np.empty((T, 3))
    for t in range(T):
        for i in range(3):
            lo = min(tri[t, 0, i], tri[t, 1, i], tri[t, 2, i])
            hi = max(tri[t, 0, i], tri[t, 1, i], tri[t, 2, i])
            tlo[t, i] = lo
            thi[t, i] = hi
            cen[t, i] = 0.5 * (lo + hi)
    order = np.arange(T)
    K = max(1, 2 * T)
    nlo = np.empty((K, 3))
    nhi = np.empty((K, 3))
    child = -np.ones((K, 2), dtype=np.int64)
    rng = np.zeros((K, 2), dtype=np.int64)
    stack = np.empty((K, 3), dtype=np.int64)
    sp = 0
    stack[0, 0] = 0
    stack[0, 1] = 0
    stack[0, 2] = T
    sp = 1
    nn = 1
    while sp > 0:
        sp -= 1
        node = stack[sp, 0]
        b = stack[sp, 1]
        e = stack[sp, 2]
        clo = np.full(3, np.inf)
        chi = np.full(3, -np.inf)
        for i in range(3):
            nlo[node, i] = np.inf
            nhi[node, i] = -np.inf
        for k in range(b, e):
            t = order[k]
            for i in range(3):
                nlo[node, i] = min(nlo[node, i], tlo[t, i])
                nhi[node, i] = max(nhi[node, i], thi[t, i])
                clo[i] = min(clo[i], cen[t, i])
                chi[i] = max(chi[i], cen[t, i])
        rng[node, 0] = b
        rng[node, 1] = e - b
        if e - b <= leaf_size:
            continue
        ax = 0
        for i in range(1, 3):
            if chi[i] - clo[i] > chi[ax] - clo[ax]:
                ax = i
        sub = order[b:e].copy()
        keys = np.empty(e - b)
        for k in range(e - b):
            keys[k] = cen[sub[k], ax]
        idx = np.argsort(keys, kind="mergesort")
        for k in range(e - b):
            order[b + k] = sub[idx[k]]
        mid = b + (e - b) // 2
        l = nn
        r = nn + 1
        nn += 2
        child[node, 0] = l
        child[node, 1] = r
        stack[sp, 0] = l
        stack[sp, 1] = b
        stack[sp, 2] = mid
        sp += 1
        stack[sp, 0] = r
        stack[sp, 1] = mid
        stack[sp, 2] = e
        sp += 1
    return order, nlo[:nn].copy(), nhi[:nn].copy(), child[:nn].copy(), rng[:nn].copy()


def build_bvh(tri: np.ndarray, *, leaf_size: int = LEAF_SIZE):
    """Build the AABB tree of triangles (T, 3, 3).

    Returns ``(tri_sorted (T,3,3), node_lo (K,3), node_hi (K,3), node_child (K,2), node_range (K,2))``;
    node 0 is the root, ``node_child = -1`` marks a leaf holding ``tri_sorted[start:start+count]``.
    """
    tri = np.ascontiguousarray(tri, dtype=np.float64)
    order, lo, hi, child, rng = _build(tri, leaf_size)
    return np.ascontiguousarray(tri[order]), lo, hi, child, rng


@njit(cache=True)
def bvh_any_overlap(root, node_lo, node_hi, node_child, node_range, tri, qlo, qhi):
    """True if any triangle's AABB overlaps the box [qlo, qhi] (nodes offset by ``root``)."""
    stack = np.empty(128, dtype=np.int64)
    sp = 0
    stack[0] = root
    sp = 1
    while sp > 0:
        sp -= 1
        nd = stack[sp]
        if (node_lo[nd, 0] > qhi[0] or node_hi[nd, 0] < qlo[0] or node_lo[nd, 1] > qhi[1]
                or node_hi[nd, 1] < qlo[1] or node_lo[nd, 2] > qhi[2] or node_hi[nd, 2] < qlo[2]):
            continue
        if node_child[nd, 0] < 0:
            st = node_range[nd, 0]
            for t in range(st, st + node_range[nd, 1]):
                ok = True
                for i in range(3):
                    lo = min(tri[t, 0, i], tri[t, 1, i], tri[t, 2, i])
                    hi = max(tri[t, 0, i], tri[t, 1, i], tri[t, 2, i])
                    if lo > qhi[i] or hi < qlo[i]:
                        ok = False
                        break
                if ok:
                    return True
        else:
            if sp + 2 > 128:
                return True  # conservative
            stack[sp] = node_child[nd, 0]
            stack[sp + 1] = node_child[nd, 1]
            sp += 2
    return False


def cylinder_triangles(length: float, radius: float, segments: int = 48) -> np.ndarray:
    """Closed prism of ``segments`` sides approximating a flat-ended cylinder of ``radius`` [m] along local z,
    from z = -length/2 to +length/2 -> triangles (T, 3, 3), counter-clockwise seen from outside."""
    a = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(segments)], axis=1)
    lo = ring + [0.0, 0.0, -0.5 * length]
    hi = ring + [0.0, 0.0, 0.5 * length]
    nxt = np.roll(np.arange(segments), -1)
    c_lo = np.broadcast_to([0.0, 0.0, -0.5 * length], (segments, 3))
    c_hi = np.broadcast_to([0.0, 0.0, 0.5 * length], (segments, 3))
    tris = [np.stack([lo, lo[nxt], hi[nxt]], 1), np.stack([lo, hi[nxt], hi], 1),   # side
            np.stack([c_hi, hi, hi[nxt]], 1), np.stack([c_lo, lo[nxt], lo], 1)]   # caps
    return np.ascontiguousarray(np.concatenate(tris), dtype=np.float64)
