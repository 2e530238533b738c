"""The rod's tube as one smooth triangle mesh, built with numpy (no loop over nodes), and a minimal GLB writer.

Around every node i a ring of ``sides`` vertices lies in the plane normal to the node tangent (the bisector of its
two edges, docs/physics.md §1.2), at distance ``radius`` from the node; ring vertex j points along
``cos θ_j d1_i + sin θ_j d2_i`` (θ_j = 2πj/sides), where d1 is the material director m1 averaged over the node's
edges and made normal to the tangent (docs/physics.md §1.3), d2 = t × d1. So the rings turn with the rod's twist and
the quads between neighbouring rings do not shear. Each end gets a flat cap (its own ring plus a centre vertex).
Normals are per vertex: radial on the rings (smooth shading), ±tangent on the caps. Colours are per vertex: a ring
takes its node's colour, so a colour map along the rod is interpolated smoothly.

viser shows per-vertex colours only for GLB assets (``scene.add_glb``); :func:`glb_bytes` packs the mesh into a
glTF 2.0 binary (positions, normals, linear-space COLOR_0, uint32 indices).
"""
from __future__ import annotations

import dataclasses
import functools
import json
import struct

import numpy as np

SIDES = 16  # vertices per ring


@dataclasses.dataclass
class TubeMesh:
    vertices: np.ndarray  # (V, 3) float32 [m]
    normals: np.ndarray  # (V, 3) float32, unit
    colors: np.ndarray  # (V, 3) uint8 sRGB
    faces: np.ndarray  # (F, 3) uint32, counter-clockwise seen from outside


def vertex_count(n_nodes: int, sides: int = SIDES) -> int:
    """Rings on every node plus two caps (a ring and a centre each)."""
    return n_nodes * sides + 2 * (sides + 1)


@functools.lru_cache(maxsize=16)
def tube_faces(n_nodes: int, sides: int = SIDES) -> np.ndarray:
    """(F, 3) triangle indices of a tube of ``n_nodes`` rings (layout of :func:`tube_mesh`); cached per size."""
    i = np.arange(n_nodes - 1)[:, None]
    j = np.arange(sides)[None, :]
    a = i * sides + j
    b = i * sides + (j + 1) % sides
    c = b + sides
    d = a + sides
    side = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 2).reshape(-1, 3)
    base0 = n_nodes * sides  # start cap: ring base0 .. base0+sides-1, centre base0+sides
    base1 = base0 + sides + 1
    jj = np.arange(sides)
    cap0 = np.stack([np.full(sides, base0 + sides), base0 + (jj + 1) % sides, base0 + jj], 1)
    cap1 = np.stack([np.full(sides, base1 + sides), base1 + jj, base1 + (jj + 1) % sides], 1)
    out = np.concatenate([side, cap0, cap1]).astype(np.uint32)
    out.setflags(write=False)
    return out


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-300), n[..., 0]


def node_frames(x: np.ndarray, m1: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, d1, d2) per node, each (N, 3) unit: the node tangent (bisector of its edges' tangents) and two
    directions normal to it. ``m1`` (N-1, 3): the material director per edge, used for d1 when given."""
    x = np.asarray(x, np.float64)
    te, le = _unit(np.diff(x, axis=0))
    if np.any(le < 1e-12):  # a zero-length edge: borrow a neighbour's direction
        ok = le >= 1e-12
        if not ok.any():
            te = np.tile([0.0, 0.0, 1.0], (len(te), 1))
        else:
            idx = np.maximum.accumulate(np.where(ok, np.arange(len(te)), -1))
            first = int(np.argmax(ok))
            idx = np.where(idx < 0, first, idx)
            te = te[idx]
    tn = np.concatenate([te[:1], te[:-1] + te[1:], te[-1:]])
    t, nt = _unit(tn)
    folded = nt < 1e-6  # the rod folds back on itself at this node: use the incoming edge
    if folded.any():
        t[folded] = np.concatenate([te[:1], te])[folded]
    if m1 is not None:
        m = np.asarray(m1, np.float64)
        ref = np.concatenate([m[:1], m[:-1] + m[1:], m[-1:]])
    else:  # one fixed axis for the whole rod: the one least aligned with its mean direction
        mean = np.abs(te.mean(axis=0))
        ref = np.tile(np.eye(3)[int(np.argmin(mean))], (len(x), 1))
    d1 = ref - np.sum(ref * t, axis=1, keepdims=True) * t
    d1, n1 = _unit(d1)
    bad = n1 < 1e-6
    if bad.any():  # reference along the tangent: any normal direction
        alt = np.where(np.abs(t[bad, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        d1[bad] = _unit(alt - np.sum(alt * t[bad], axis=1, keepdims=True) * t[bad])[0]
    d2 = np.cross(t, d1)
    return t, d1, d2


def tube_mesh(x: np.ndarray, radius, *, m1: np.ndarray | None = None, colors: np.ndarray | None = None,
              sides: int = SIDES) -> TubeMesh:
    """The tube around centreline ``x`` (N, 3) [m] of cross-section ``radius`` [m] (one value, or one per node for a
    non-uniform rod); ``colors`` (N, 3) uint8 per node (default grey); ``m1`` (N-1, 3) material directors
    (optional, see module docstring)."""
    x = np.asarray(x, np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or len(x) < 2:
        raise ValueError(f"tube_mesh: node positions must be (N >= 2, 3), got {x.shape}")
    n = len(x)
    rad = np.asarray(radius, np.float64)
    if rad.ndim == 1 and rad.shape != (n,):
        raise ValueError(f"tube_mesh: per-node radii must be (N,) = ({n},), got {rad.shape}")
    if not np.all(np.isfinite(x)) or rad.ndim > 1 or not (np.all(np.isfinite(rad)) and np.all(rad > 0)):
        raise ValueError("tube_mesh: node positions and radius must be finite (radius > 0)")
    radius = rad[:, None, None] if rad.ndim == 1 else float(rad)
    t, d1, d2 = node_frames(x, m1)
    th = 2.0 * np.pi * np.arange(sides) / sides
    radial = np.cos(th)[None, :, None] * d1[:, None, :] + np.sin(th)[None, :, None] * d2[:, None, :]  # (N, k, 3)
    rr = radius * radial  # (N, k, 3)
    ring = (x[:, None, :] + rr).reshape(-1, 3)
    cap_v, cap_n = [], []
    for end, sign in ((0, -1.0), (n - 1, 1.0)):
        cap_v += [x[end] + rr[end], x[end][None]]
        cap_n.append(np.repeat(sign * t[end][None], sides + 1, axis=0))
    verts = np.concatenate([ring] + cap_v)
    normals = np.concatenate([radial.reshape(-1, 3)] + cap_n)
    c = np.tile(np.array([200, 200, 200], np.uint8), (n, 1)) if colors is None else np.asarray(colors, np.uint8)
    if c.shape != (n, 3):
        raise ValueError(f"tube_mesh: colors must be (N, 3) = ({n}, 3), got {c.shape}")
    vcol = np.concatenate([np.repeat(c, sides, axis=0), np.repeat(c[:1], sides + 1, axis=0),
                           np.repeat(c[-1:], sides + 1, axis=0)])
    return TubeMesh(verts.astype(np.float32), normals.astype(np.float32), vcol, tube_faces(n, sides))


def rods_mesh(x: np.ndarray, radius, offsets, *, m1: np.ndarray | None = None, colors: np.ndarray | None = None,
              sides: int = SIDES) -> TubeMesh:
    """One mesh of several rods' tubes: the nodes ``x`` (N, 3) of a chain split at ``offsets`` (R+1,) (each rod's
    first node, then N; ``sim.Model.rod_node_offsets``), each rod its own capped tube (the edge joining two rods
    is not drawn). ``radius``, ``m1`` and ``colors`` over the whole chain as for :func:`tube_mesh`; ``offsets``
    None or of one rod: :func:`tube_mesh`."""
    if offsets is None or len(offsets) <= 2:
        return tube_mesh(x, radius, m1=m1, colors=colors, sides=sides)
    parts = []
    for a, b in zip(offsets[:-1], offsets[1:]):
        a, b = int(a), int(b)
        r = radius if np.ndim(radius) == 0 else np.asarray(radius)[a:b]
        parts.append(tube_mesh(x[a:b], r, m1=None if m1 is None else m1[a:b - 1],
                               colors=None if colors is None else colors[a:b], sides=sides))
    base = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    return TubeMesh(np.concatenate([p.vertices for p in parts]), np.concatenate([p.normals for p in parts]),
                    np.concatenate([p.colors for p in parts]),
                    np.concatenate([p.faces + np.uint32(o) for p, o in zip(parts, base)]).astype(np.uint32))


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    s = np.asarray(c, np.float32) / 255.0
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4).astype(np.float32)


def glb_bytes(mesh: TubeMesh, *, roughness: float = 0.55) -> bytes:
    """A glTF 2.0 binary holding ``mesh`` (one node, one primitive with POSITION, NORMAL, COLOR_0, indices)."""
    v = np.ascontiguousarray(mesh.vertices, np.float32)
    nrm = np.ascontiguousarray(mesh.normals, np.float32)
    col = np.ascontiguousarray(_srgb_to_linear(mesh.colors))  # glTF vertex colours are linear
    idx = np.ascontiguousarray(mesh.faces, np.uint32).reshape(-1)
    blobs = [v.tobytes(), nrm.tobytes(), col.tobytes(), idx.tobytes()]
    offsets = np.concatenate([[0], np.cumsum([len(b) for b in blobs])]).tolist()
    views = [{"buffer": 0, "byteOffset": offsets[i], "byteLength": len(b),
              "target": 34963 if i == 3 else 34962} for i, b in enumerate(blobs)]
    nv = len(v)
    accessors = [
        {"bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3",
         "min": v.min(axis=0).tolist(), "max": v.max(axis=0).tolist()},
        {"bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3"},
        {"bufferView": 2, "componentType": 5126, "count": nv, "type": "VEC3"},
        {"bufferView": 3, "componentType": 5125, "count": len(idx), "type": "SCALAR"},
    ]
    doc = {"asset": {"version": "2.0", "generator": "rodlab workbench.view.tube"}, "scene": 0,
           "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2}, "indices": 3,
                                       "material": 0}]}],
           "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
                                                   "roughnessFactor": roughness}}],
           "buffers": [{"byteLength": offsets[-1]}], "bufferViews": views, "accessors": accessors}
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    binary = b"".join(blobs)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(js), b"JSON") + js
            + struct.pack("<I4s", len(binary), b"BIN\0") + binary)
