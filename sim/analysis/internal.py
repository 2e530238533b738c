"""Internal loads of a rod: the section forces and moments its elastic energy carries (docs/physics.md §2.5).

Each is the derivative of an element's energy with respect to its own strain, so it is what the material holds at
that place, in the units a beam formula gives:

* axial force of edge j [N], tension positive: ``N_j = EA_j ε_j`` with ``ε_j = |e^j| / l̄_j − 1``;
* bending moments at interior node i [N·m], in the material frame: ``M_c,i = EI_c,i (κ_c,i − κ̄_c,i) / l_i``,
  c ∈ {1, 2} (κ1 bends about m2, κ2 about m1, docs/physics.md §1.5);
* twisting moment at interior node i [N·m]: ``T_i = GJ_i (τ_i − τ̄_i) / l_i``.

Rows a rod has no element for (each rod's end nodes, the joint edge between two rods) are 0. In 2-D mode the
in-plane moment sits in the 3-D component that is in-plane for the rod (``Model.planar_component``, §1.6), the other
component and the twist are 0. At a static equilibrium these equal the loads of the elastica: the moment at a node
of a cantilever is the tip load times its lever arm, the axial force of a hanging rod the weight below the edge.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.geometry.curvature import integrated_twist, material_curvature
from sim.scene.model import Model

__all__ = ["InternalLoads", "internal_loads"]


@dataclass(frozen=True)
class InternalLoads:
    """Section loads of a batch of rods (leading axes as the positions given).

    axial     (..., N−1) [N] axial force of each edge, tension positive (0 on a joint edge between two rods).
    bending   (..., N, 2) [N·m] bending moments (M1, M2) at the nodes, paired with (κ1, κ2).
    twisting  (..., N) [N·m] twisting moment at the nodes (0 in 2-D).
    """

    axial: np.ndarray
    bending: np.ndarray
    twisting: np.ndarray


def _rod_ends(model: Model) -> np.ndarray:
    """(N,) bool: the first and last node of every rod (they carry no bending or twisting element)."""
    n = model.node_count
    off = np.asarray(model.rod_node_offsets, np.int64)
    off = off if off.size >= 2 else np.array([0, n], np.int64)
    ends = np.zeros(n, bool)
    ends[off[:-1]] = True
    ends[off[1:] - 1] = True
    return ends


def _planar_component(model: Model) -> np.ndarray:
    """(N,) which 3-D curvature component is in-plane at each node (2-D, each rod its own, docs/physics.md §1.6)."""
    comp = np.full(model.node_count, int(model.planar_component), np.int64)
    off = np.asarray(model.rod_node_offsets, np.int64)
    if model.rod_planar and off.size == len(model.rod_planar) + 1:
        for (c, _sign), a, b in zip(model.rod_planar, off[:-1], off[1:]):
            comp[a:b] = int(c)
    return comp


def internal_loads(model: Model, node_pos, m1, m2, kappa_bar, tau_bar=None) -> InternalLoads:
    """Internal loads of the configuration ``node_pos`` (..., N, 3) [m] with material directors ``m1``, ``m2``
    (..., N−1, 3) (``Simulator.material_frames``) under the natural curvature ``kappa_bar`` (..., N, 2) and twist
    ``tau_bar`` (..., N) [rad] (``Control``; None: no natural twist). ``Simulator.internal_loads(state, ctrl)`` is
    the same for a State."""
    x = np.asarray(node_pos, np.float64)
    n = model.node_count
    if x.shape[-2:] != (n, 3):
        raise ValueError(f"node_pos has shape {x.shape}; the model has {n} nodes, so (..., {n}, 3) is needed")
    kb = np.asarray(kappa_bar, np.float64)
    if kb.shape[-2:] != (n, 2):
        raise ValueError(f"kappa_bar has shape {kb.shape}; (..., {n}, 2) is needed")
    vor = np.asarray(model.voronoi_length, np.float64)
    inner = ~_rod_ends(model)
    # stretching: every edge (a joint edge has EA = 0)
    elen = np.linalg.norm(np.diff(x, axis=-2), axis=-1)
    axial = np.asarray(model.edge_EA, np.float64) * (elen / np.asarray(model.rest_edge_length, np.float64) - 1.0)
    kappa = material_curvature(x, np.asarray(m1, np.float64), np.asarray(m2, np.float64))
    ei = np.stack([np.asarray(model.node_EI1, np.float64), np.asarray(model.node_EI2, np.float64)], axis=-1)
    bending = np.zeros(np.broadcast_shapes(kappa.shape, kb.shape))
    twisting = np.zeros(bending.shape[:-1])
    if model.mode == "2d":
        # kappa_bar[..., 0] holds the in-plane 3-D component (§1.6), compared with the same component of the rod's
        rows, comp = np.arange(n), _planar_component(model)
        bending[..., rows, comp] = ei[rows, comp] * (kappa[..., rows, comp] - kb[..., 0]) / vor
    else:
        bending[...] = ei * (kappa - kb) / vor[:, None]
        tau = integrated_twist(x, m1)
        tb = 0.0 if tau_bar is None else np.asarray(tau_bar, np.float64)
        twisting[...] = np.asarray(model.node_GJ, np.float64) * (tau - tb) / vor
    bending[..., ~inner, :] = 0.0
    twisting[..., ~inner] = 0.0
    return InternalLoads(axial=axial, bending=bending, twisting=twisting)
