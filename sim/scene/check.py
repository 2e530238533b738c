"""Load-time scene checks that are warnings, not errors: a rod that starts inside an obstacle.

:func:`rod_obstacle_overlaps` returns the obstacles that the rod's rest (initial) configuration penetrates,
measured with the simulator's own contact geometry (sim/contact/obstacles.py: the gap between the rod's surface,
radius ``rod.radius``, and the obstacle). Such a rod is pushed out violently in the first steps (the contact
force of the penetration guard), so ``rodlab sim`` prints a warning and the workbench should show one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.contact.obstacles import find_candidates, smallest_gap
from sim.contact.world import contact_radii, spec_contact_data

__all__ = ["Overlap", "rod_obstacle_overlaps", "overlap_warning"]


@dataclass(frozen=True)
class Overlap:
    """Obstacle ``index`` (scene order), its ``name`` and ``type``, and how deep the rod starts inside [m]."""

    index: int
    name: str
    type: str
    depth: float


def rod_obstacle_overlaps(model, *, tolerance: float = 0.0) -> list[Overlap]:
    """Obstacles the rod's rest configuration of ``model`` (a :class:`sim.Model`) penetrates deeper than
    ``tolerance`` [m], deepest first. Empty without obstacles."""
    M = model.obstacles.count
    if M == 0:
        return []
    cd = spec_contact_data(model.obstacles, M, model.node_count, model.edge_radius,
                           active=np.eye(M, dtype=np.bool_))  # env o sees obstacle o only
    x = np.ascontiguousarray(model.rest_node_pos, dtype=np.float64)
    link = np.ones(model.node_count - 1, np.uint8)  # joint edges between rods are never candidates
    if len(getattr(model, "edge_link", ())) == model.node_count - 1:
        link = np.asarray(model.edge_link, dtype=np.uint8)
    out = []
    for o in range(M):
        find_candidates(o, cd, x, x, 0.0, link)
        gap = float(smallest_gap(o, cd, x, contact_radii(model.edge_radius)))
        if gap < -tolerance:
            spec = model.spec.obstacles[o]
            out.append(Overlap(o, getattr(spec, "name", "") or "", getattr(spec, "type", "?"), -gap))
    return sorted(out, key=lambda ov: -ov.depth)


def overlap_warning(overlaps: list[Overlap], where: str = "<scene>") -> str:
    """One human-readable warning line for the overlaps ('' when none)."""
    if not overlaps:
        return ""
    parts = [f"obstacle[{ov.index}]{' ' + repr(ov.name) if ov.name else ''} ({ov.type}, {ov.depth * 1e3:.1f} mm deep)"
             for ov in overlaps]
    return (f"warning: {where}: the rod starts inside {', '.join(parts)}; it will be pushed out violently in the "
            "first steps (move the rod or the obstacle)")
