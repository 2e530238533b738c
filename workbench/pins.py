"""Inspect any point of the rod: what a pinned readout shows at a node, from one drawn :class:`Frame`.

Click the rod and a readout is pinned at the nearest node; it follows the node as the rod moves, live and in replays.
The values are the frame's own, so a readout always belongs to the frame drawn: position and velocity, the integrated
material curvature κ1, κ2 (``sim.curvature.material_curvature``, docs/physics.md §1.4) beside the natural curvature
the controller commands there (live sessions), the integrated twist, and the axial strain (mean of the node's edges).
"""
from __future__ import annotations

import numpy as np

from workbench import coloring
from workbench.frame import Frame

MAX_PINS = 4  # readouts pinned at once (a fifth click replaces the oldest)


def ray_nearest_node(x: np.ndarray, nodes, origin, direction) -> int:
    """Of ``nodes`` (indices into node positions ``x`` (N, 3)), the one nearest the pointer's ray."""
    o = np.asarray(origin, np.float64)
    d = np.asarray(direction, np.float64)
    d = d / max(float(np.linalg.norm(d)), 1e-300)
    cand = np.asarray(list(nodes), dtype=np.int64)
    rel = x[cand] - o
    off = rel - np.outer(rel @ d, d)
    return int(cand[np.argmin(np.linalg.norm(off, axis=1))])


def node_readout(fr: Frame, node: int) -> dict[str, float | np.ndarray]:
    """Named values at ``node`` of frame ``fr``: ``position`` (3,) [m], ``velocity`` (3,) [m/s] (when the frame has
    velocities), ``κ1``, ``κ2``, ``twist`` [rad] (integrated; when the frame has material frames), ``κ̄1``, ``κ̄2``
    [rad] (the commanded natural curvature, live sessions), ``strain`` [-]."""
    out: dict[str, float | np.ndarray] = {"position": np.asarray(fr.node_pos[node], np.float64).copy()}
    vel = getattr(fr, "node_vel", None)
    if vel is not None:
        out["velocity"] = np.asarray(vel[node], np.float64).copy()
    off = getattr(fr, "rod_offsets", None)
    starts = np.asarray(off if off is not None else (0, len(fr.node_pos)), dtype=np.int64)
    rod_end = node in set(starts[:-1].tolist()) or node + 1 in set(starts[1:].tolist())
    for name in ("κ1", "κ2", "twist", "strain"):
        v = coloring.node_values(fr, name)
        if v is not None:  # a rod's end node bends and twists nothing (the colour map copies its neighbour's)
            out[name] = 0.0 if rod_end and name != "strain" else float(v[node])
    kb = getattr(fr, "kappa_bar", None)
    if kb is not None:
        k = np.asarray(kb, np.float64).reshape(-1, 2)[node]
        out["κ̄1"], out["κ̄2"] = float(k[0]), float(k[1])
    return out


def readout_text(node: int, r: dict) -> str:
    """The readout as a short label."""
    p = r["position"]
    parts = [f"node {node} · ({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f}) m"]
    if "velocity" in r:
        parts.append(f"|v| {float(np.linalg.norm(r['velocity'])):.3g} m/s")
    for a in ("κ1", "κ2"):
        if a in r:
            bar = f"κ̄{a[1]}"
            parts.append(f"{a} {r[a]:+.3f}" + (f" (κ̄ {r[bar]:+.3f})" if bar in r else "") + " rad")
    if "twist" in r:
        parts.append(f"twist {r['twist']:+.3f} rad")
    if "strain" in r:
        parts.append(f"ε {r['strain']:+.2e}")
    return " · ".join(parts)
