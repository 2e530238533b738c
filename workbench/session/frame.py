"""What the 3D view draws for one instant: :class:`Frame`, plus small geometry helpers.

A ``Frame`` is produced from the live simulator (``workbench.session.simbridge``) or from a recorded
episode (``workbench.session.replay``); the view renders both the same way, so the overlays match.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from sim.geometry import curvature_binormal, quat_to_matrix


@dataclasses.dataclass
class Frame:
    """One drawable instant of one rod.

    Attributes:
        node_pos: (N, 3) node positions [m].
        node_vel: (N, 3) node velocities [m/s] (live sessions), or None.
        rod_radius: cross-section radius [m] (a non-uniform rod: its largest).
        node_radius: (N,) radius at each node [m] of a non-uniform rod (the tube follows it), or None.
        m1, m2: (N-1, 3) material directors per edge (unit) or None when unknown.
        node_curvature: (N,) magnitude of the integrated curvature |κ| at nodes [-] (0 at the ends).
        edge_strain: (N-1,) axial strain |e_j|/l0_j - 1 [-], or None.
        contact_points: (K, 3) rod-side contact points [m].
        contact_forces: (K, 3) contact force on the rod [N] (normal + friction).
        contact_normals: (K, 3) unit normals (obstacle -> rod); contact_normal_force: (K,) [N].
        targets: (T, 3) target marker positions [m].
        time: simulated time [s].
        scalars: named live values (reward, reward terms, tip error, newton_iters, ...).
        rod_offsets: (R+1,) where each rod's nodes start in ``node_pos`` (then N) when the scene has several rods
            (``sim.Model.rod_node_offsets``; drawn as separate tubes), else None.
        hand: (2, 3) [m] the grabbed node and the hand while the rod is pulled (``workbench.session.pull``), else None;
            hand_force: the pull's total force [N].
        edge_axial_force: (N-1,) axial force of each edge [N], tension positive, and node_moment: (N, 3) the bending
            moments M1, M2 and the twisting moment T at the nodes [N m] (``sim.analysis.internal``, docs/physics.md §2.5), live
            sessions only, else None.
        contact_edge: (K,) the rod edge of each contact row, contact_gap: (K,) its gap [m] (negative: overlap),
            contact_obstacle: (K,) the obstacle it touches (−1: another edge, contact_partner_edge (K,) that edge,
            −1 on an obstacle row), or None when unknown (``sim.StepStats``' contact rows).
    """

    node_pos: np.ndarray
    rod_radius: float
    node_radius: np.ndarray | None = None
    m1: np.ndarray | None = None
    m2: np.ndarray | None = None
    node_curvature: np.ndarray | None = None
    kappa_bar: np.ndarray | None = None  # (N, 2) commanded (natural) integrated curvature, live sessions only
    edge_strain: np.ndarray | None = None
    contact_points: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    contact_forces: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    contact_normals: np.ndarray | None = None
    contact_normal_force: np.ndarray | None = None
    targets: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    target_wxyz: np.ndarray | None = None
    time: float = 0.0
    scalars: dict[str, float] = dataclasses.field(default_factory=dict)
    rod_offsets: np.ndarray | None = None
    hand: np.ndarray | None = None
    node_vel: np.ndarray | None = None
    hand_force: np.ndarray | None = None
    edge_axial_force: np.ndarray | None = None
    node_moment: np.ndarray | None = None
    contact_edge: np.ndarray | None = None
    contact_gap: np.ndarray | None = None
    contact_obstacle: np.ndarray | None = None
    contact_partner_edge: np.ndarray | None = None

    @property
    def tip(self) -> np.ndarray:
        return self.node_pos[-1]


def quat_from_rpy_deg(rpy) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of roll, pitch, yaw [deg]: R = Rz(yaw) · Ry(pitch) · Rx(roll) (rotations about
    the fixed world x, then y, then z)."""
    r, p, y = np.radians(np.asarray(rpy, np.float64).reshape(3)) / 2.0
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def rpy_deg_from_quat(wxyz) -> np.ndarray:
    """(roll, pitch, yaw) [deg] of a quaternion (w, x, y, z), inverse of :func:`quat_from_rpy_deg`; pitch in
    [-90, 90], roll and yaw in (-180, 180] (at pitch ±90° roll is 0 and yaw carries the rest)."""
    R = quat_to_matrix(np.asarray(wxyz, np.float64).reshape(4))
    pitch = np.arcsin(np.clip(-R[2, 0], -1.0, 1.0))
    if abs(R[2, 0]) < 1.0 - 1e-9:
        roll, yaw = np.arctan2(R[2, 1], R[2, 2]), np.arctan2(R[1, 0], R[0, 0])
    else:  # gimbal lock
        roll, yaw = 0.0, np.arctan2(-R[0, 1], R[1, 1])
    return np.degrees(np.array([roll, pitch, yaw]))


def curvature_magnitude(node_pos: np.ndarray, rod_offsets=None) -> np.ndarray:
    """Magnitude of the integrated curvature binormal, |κb_i| = 2 tan(φ_i/2), at every node (ends 0) (the material
    components κ1, κ2 are ``sim.geometry.curvature.material_curvature``). node_pos (..., N, 3) -> (..., N). With ``rod_offsets`` (several
    rods, see :class:`Frame`) each rod's end nodes are 0 too: the edge joining two rods bends nothing."""
    k = np.linalg.norm(curvature_binormal(node_pos), axis=-1)
    inner = np.asarray(rod_offsets if rod_offsets is not None else (), np.int64)[1:-1]
    if len(inner):
        k[..., inner - 1] = 0.0
        k[..., inner] = 0.0
    return k


def several_rods(rod_offsets) -> np.ndarray | None:
    """``rod_offsets`` as int64 when they split the nodes into several rods, else None (one rod: drawn whole)."""
    if rod_offsets is None:
        return None
    off = np.asarray(rod_offsets, np.int64)
    return off if len(off) > 2 else None


def joint_edges(rod_offsets) -> np.ndarray:
    """(R-1,) indices of the edges that join two rods (from a rod's last node to the next rod's first; no part of
    either rod), for ``rod_offsets`` (R+1,) or None (one rod: none)."""
    off = several_rods(rod_offsets)
    return np.zeros(0, np.int64) if off is None else off[1:-1] - 1


def rod_edges(n_nodes: int, rod_offsets=None) -> np.ndarray:
    """(E,) indices of the edges that belong to a rod (all N-1 but the joint edges)."""
    keep = np.ones(max(int(n_nodes) - 1, 0), dtype=bool)
    j = joint_edges(rod_offsets)
    keep[j[(j >= 0) & (j < len(keep))]] = False
    return np.flatnonzero(keep)


def edge_mean_at_nodes(values) -> np.ndarray:
    """(N,) per-edge values (N-1,) brought to the nodes: the mean of each node's edges (one edge at either end)."""
    v = np.asarray(values, np.float64)
    return np.concatenate([v[:1], 0.5 * (v[:-1] + v[1:]), v[-1:]])


def edge_strain(node_pos: np.ndarray, rest_length: np.ndarray) -> np.ndarray:
    """Axial strain per edge: (..., N, 3), (N-1,) -> (..., N-1)."""
    return np.linalg.norm(np.diff(node_pos, axis=-2), axis=-1) / rest_length - 1.0


def colormap(values: np.ndarray, vmax: float) -> np.ndarray:
    """Map values in [0, vmax] to a blue→green→red ramp; returns (..., 3) uint8."""
    s = np.clip(np.asarray(values, dtype=np.float64) / max(vmax, 1e-12), 0.0, 1.0)
    r = np.clip(2.0 * s - 0.5, 0.0, 1.0)
    g = np.clip(1.5 - np.abs(4.0 * s - 2.0), 0.0, 1.0) * 0.85 + 0.1
    b = np.clip(1.5 - 2.0 * s, 0.0, 1.0)
    return (np.stack([r, g, b], -1) * 255).astype(np.uint8)
