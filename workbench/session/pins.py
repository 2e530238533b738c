"""Inspect any point of the rod: what a pinned readout shows at a node, from one drawn :class:`Frame`.

Click the rod and a readout is pinned at the nearest node; it follows the node as the rod moves, live and in replays.
The values are the frame's own, so a readout always belongs to the frame drawn: position and velocity, the integrated
material curvature κ1, κ2 (``sim.geometry.curvature.material_curvature``, docs/physics.md §1.4) beside the natural curvature
the controller commands there (live sessions), the integrated twist, the axial strain (mean of the node's edges),
and in live sessions what the material carries there (``sim.analysis.internal``, docs/physics.md §2.5): the axial force (mean
of the node's edges), the bending moments M1, M2 and the twisting moment T, and the contact on the node's edges (the
sum of their contact forces and the smallest gap).
"""
from __future__ import annotations

import numpy as np

from sim.analysis import internal_loads
from sim.geometry import integrated_twist, material_curvature
from workbench.session import coloring
from workbench.session.frame import Frame, edge_mean_at_nodes

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
    [rad] (the commanded natural curvature, live sessions), ``strain`` [-]; live sessions also ``axial force`` [N],
    ``M1``, ``M2``, ``T`` [N m], ``contact force`` (3,) [N] on the node's edges and their smallest ``gap`` [m]
    (only while in contact)."""
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
    edges = [j for j in (node - 1, node) if 0 <= j < len(fr.node_pos) - 1]
    fa = getattr(fr, "edge_axial_force", None)
    if fa is not None:
        out["axial force"] = float(edge_mean_at_nodes(fa)[node])
    mom = getattr(fr, "node_moment", None)
    if mom is not None:
        out["M1"], out["M2"], out["T"] = (float(v) for v in np.asarray(mom, np.float64)[node])
    ce, gap = getattr(fr, "contact_edge", None), getattr(fr, "contact_gap", None)
    if ce is not None and gap is not None:
        rows = np.isin(np.asarray(ce), edges)
        if rows.any():
            out["contact force"] = np.asarray(fr.contact_forces, np.float64)[rows].sum(axis=0)
            out["gap"] = float(np.asarray(gap, np.float64)[rows].min())
        else:
            out["contact force"] = np.zeros(3)
    return out


def readout_text(node: int, r: dict) -> str:
    """The readout as a short label: one line each for where the node is, how it is strained, what it carries and its
    contact (the lines it has values for)."""
    p = r["position"]
    where = [f"node {node} · ({p[0]:+.3f}, {p[1]:+.3f}, {p[2]:+.3f}) m"]
    if "velocity" in r:
        where.append(f"|v| {float(np.linalg.norm(r['velocity'])):.3g} m/s")
    strain = []
    for a in ("κ1", "κ2"):
        if a in r:
            bar = f"κ̄{a[1]}"
            strain.append(f"{a} {r[a]:+.3f}" + (f" (κ̄ {r[bar]:+.3f})" if bar in r else "") + " rad")
    if "twist" in r:
        strain.append(f"twist {r['twist']:+.3f} rad")
    if "strain" in r:
        strain.append(f"ε {r['strain']:+.2e}")
    carried = []
    if "axial force" in r:
        carried.append(f"N {r['axial force']:+.3g} N")
    if "M1" in r:
        carried.append(f"M1 {r['M1']:+.3g} · M2 {r['M2']:+.3g} · T {r['T']:+.3g} N·m")
    lines = [" · ".join(x) for x in (where, strain, carried) if x]
    if "contact force" in r:
        f = float(np.linalg.norm(r["contact force"]))
        lines.append(f"contact {f:.3g} N · gap {1000.0 * r['gap']:+.2f} mm" if "gap" in r else "no contact")
    return "\n".join(lines)


#: the plots of pinned values against time: recorded-name prefix -> (title with unit, component names)
PIN_PLOTS = {"pin_curvature": ("pinned nodes: curvature κ1, κ2 and twist [rad]", ("κ1", "κ2", "twist")),
             "pin_moment": ("pinned nodes: bending moments M1, M2 and twisting moment T [N·m]", ("M1", "M2", "T")),
             "pin_axial": ("pinned nodes: axial force [N] (mean of the node's edges)", ("N",))}


def node_table(sim, snap) -> np.ndarray:
    """(N, 7) per node of a live snapshot ``snap`` (State, Control) of env 0: κ1, κ2, twist [rad], M1, M2, T [N m]
    and the axial force [N] (mean of the node's edges), as the simulator has them (``sim.analysis.internal``)."""
    state, ctrl = snap
    m1, m2, _t = sim.material_frames(state)
    x, m1, m2 = np.asarray(state.node_pos[0]), m1[0], m2[0]
    loads = internal_loads(sim.model, x, m1, m2, ctrl.kappa_bar[0], ctrl.tau_bar[0])
    node_axial = edge_mean_at_nodes(loads.axial)
    tw = integrated_twist(x, m1) if sim.model.mode == "3d" else np.zeros(len(x))
    return np.column_stack([material_curvature(x, m1, m2), tw, loads.bending, loads.twisting, node_axial])


class PinSeries:
    """The pinned nodes' values over the live history, for the Plots tab: each snapshot's table (:func:`node_table`)
    is computed once and kept while the snapshot is in the window, so pinning a node shows its past at once."""

    def __init__(self):
        # id(snapshot) -> (snapshot, table): the snapshot is kept with its table, so its id is not reused meanwhile
        self._tables: dict[int, tuple[object, np.ndarray]] = {}

    def series(self, sim, items, pins) -> dict[str, np.ndarray]:
        """Recorded name (``pin_moment/node 12 M1`` ...) -> values over ``items`` (history snapshots)."""
        pins = [int(p) for p in pins]
        if not pins or not items:
            self._tables.clear()
            return {}
        tables = []
        for it in items:
            held = self._tables.get(id(it))
            if held is None or held[0] is not it:
                n = np.shape(it.sim[0].node_pos)[1]  # a snapshot of another rod (the scene changed): no values
                tab = node_table(sim, it.sim) if n == sim.model.node_count else np.full((n, 7), np.nan)
                held = self._tables[id(it)] = (it, tab)
            tables.append(held[1])
        keep = {id(it) for it in items}
        for k in [k for k in self._tables if k not in keep]:
            del self._tables[k]
        out: dict[str, np.ndarray] = {}
        col = 0
        for prefix, (_title, names) in PIN_PLOTS.items():
            for j, comp in enumerate(names):
                for p in pins:
                    vals = np.array([t[p, col + j] if p < len(t) else np.nan for t in tables])
                    out[f"{prefix}/node {p}" + (f" {comp}" if len(names) > 1 else "")] = vals
            col += len(names)
        if sim.model.mode == "2d":  # no twist, no twisting moment in the plane
            out = {k: v for k, v in out.items() if not (k.endswith(" twist") or k.endswith(" T"))}
        return out
