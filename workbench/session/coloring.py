"""Rod colouring: the quantity shown along the rod, its colour map and range, and the colour bar drawn in the page.

Quantities (per node, integrated values as in docs/physics.md §1.4, dimensionless): signed material curvatures κ1
and κ2 (``sim.geometry.curvature.material_curvature``), the twist between neighbouring edges (the angle of m1 about the
tangent after parallel transport), the axial stretch of the edges (ε = |e|/|ē| − 1), the curvature magnitude |κ|,
and the commanded − actual curvature |κ̄ − κ| (natural curvature set by teleop or a policy, minus the rod's own).
Signed quantities use a blue–grey–red map centred on 0, magnitudes a blue–green–red ramp from 0.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from sim.geometry import curvature_binormal, integrated_twist, material_curvature
from workbench.session.frame import Frame, colormap, edge_mean_at_nodes

#: "curvature" is |κ|, "strain" the axial stretch ε
QUANTITIES = ("curvature", "κ1", "κ2", "twist", "strain", "commanded − actual", "none")
LABELS = {"curvature": "|κ| curvature", "strain": "axial strain ε"}
SIGNED = {"κ1", "κ2", "twist", "strain"}
UNITS = {"curvature": "rad", "κ1": "rad", "κ2": "rad", "twist": "rad", "strain": "-", "commanded − actual": "rad"}


def node_values(fr: Frame, quantity: str) -> np.ndarray | None:
    """(N,) values of ``quantity`` at the nodes (end nodes copy their neighbour), or None when the frame lacks what
    it needs (material frames for κ1, κ2, twist; the natural curvature for commanded − actual). Several rods
    (``fr.rod_offsets``): each rod's values on its own (the edge joining two rods is no part of either)."""
    off = getattr(fr, "rod_offsets", None)
    if off is None or len(off) <= 2:
        return _rod_values(fr, quantity)
    parts = []
    for a, b in zip(off[:-1], off[1:]):
        a, b = int(a), int(b)

        def cut(v, stop):
            return None if v is None else np.asarray(v)[a:stop]
        sub = dataclasses.replace(fr, node_pos=np.asarray(fr.node_pos)[a:b], m1=cut(fr.m1, b - 1),
                                  m2=cut(fr.m2, b - 1), kappa_bar=cut(getattr(fr, "kappa_bar", None), b),
                                  edge_strain=cut(fr.edge_strain, b - 1), rod_offsets=None)
        v = _rod_values(sub, quantity)
        if v is None:
            return None
        parts.append(v)
    return np.concatenate(parts)


def _rod_values(fr: Frame, quantity: str) -> np.ndarray | None:
    x = np.asarray(fr.node_pos, np.float64)
    if quantity == "curvature":
        v = np.linalg.norm(curvature_binormal(x), axis=1)
    elif quantity in ("κ1", "κ2", "twist", "commanded − actual"):
        if fr.m1 is None or fr.m2 is None:
            return None
        m1, m2 = np.asarray(fr.m1, np.float64), np.asarray(fr.m2, np.float64)
        if quantity == "twist":
            v = integrated_twist(x, m1)
        else:
            k = material_curvature(x, m1, m2)
            if quantity == "commanded − actual":
                kb = getattr(fr, "kappa_bar", None)
                if kb is None:
                    return None
                v = np.linalg.norm(np.asarray(kb, np.float64).reshape(-1, 2) - k, axis=1)
            else:
                v = k[:, 0 if quantity == "κ1" else 1]
    elif quantity == "strain":
        if fr.edge_strain is None:
            return None
        return edge_mean_at_nodes(fr.edge_strain)
    else:
        return None
    v = np.asarray(v, np.float64).copy()
    if len(v) > 2:
        v[0], v[-1] = v[1], v[-2]
    return v


def value_range(values: np.ndarray, quantity: str, fixed: float | None = None) -> tuple[float, float]:
    """(lo, hi) of the colour map: ±max|v| for signed quantities, [0, max] for magnitudes; ``fixed`` sets max."""
    top = float(fixed) if fixed is not None else float(np.max(np.abs(values))) if len(values) else 0.0
    top = max(top, 1e-6)
    return (-top, top) if quantity in SIGNED else (0.0, top)


def colors(values: np.ndarray, lo: float, hi: float, quantity: str) -> np.ndarray:
    """(N, 3) uint8 colours."""
    v = np.asarray(values, np.float64)
    if quantity not in SIGNED:
        return colormap(v - lo, hi - lo)
    s = np.clip(v / max(hi, 1e-12), -1.0, 1.0)[:, None]
    white = np.array([0.72, 0.72, 0.72])  # a grey centre: 0 stays visible against the light background
    red, blue = np.array([0.80, 0.15, 0.12]), np.array([0.15, 0.35, 0.80])
    c = np.where(s >= 0, white + s * (red - white), white - s * (blue - white))
    return (c * 255).astype(np.uint8)


def colorbar_html(quantity: str, lo: float, hi: float) -> str:
    """A horizontal colour bar with its range and unit (HTML for ``gui.add_html``)."""
    if quantity == "none":
        return ""
    if quantity in SIGNED:
        grad = "rgb(38,89,204), rgb(184,184,184), rgb(204,38,31)"
    else:
        grad = ", ".join(f"rgb({r},{g},{b})" for r, g, b in colormap(np.linspace(0, 1, 5), 1.0))
    mid = 0.5 * (lo + hi)
    return (f'<div class="rodlab-colorbar" style="padding:0 0.75em;font-size:0.8em">'
            f'<div>colour: {LABELS.get(quantity, quantity)} [{UNITS.get(quantity, "-")}]</div>'
            f'<div style="height:10px;border-radius:3px;background:linear-gradient(to right, {grad})"></div>'
            f'<div style="display:flex;justify-content:space-between">'
            f'<span class="lo">{lo:.3g}</span><span>{mid:.3g}</span><span class="hi">{hi:.3g}</span></div></div>')
