"""Model: frozen parameters of one rod scene (docs/physics.md §1.2, §1.5), built from a SceneSpec.

Arrays are read-only. Shapes: N nodes, N-1 edges; ``dof_*`` arrays are per DOF of one env, flattened
node-major: 3-D ``4N`` ([x, y, z, θ] per node, θ of the last node a dummy), 2-D ``2N`` ([x, z]).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from sim.contact.world import ObstacleGeometry
from sim.geometry.curvature import material_curvature
from sim.geometry.frames import initial_reference_frames
from sim.scene.boundary import (
    FrameLoads,
    RotatingFix,
    fixed_dofs,
    frame_load_arrays,
    held_edges,
    load_arrays,
    motion_arrays,
    rod_span,
    rotating_fixes,
)
from sim.scene.section import section_of
from sim.scene.spec import SceneSpec
from sim.scene.validate import check_scene

__all__ = ["Model", "build_model", "planar_nodes"]


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Model:
    """Frozen rod + solver parameters. Units SI; curvatures integrated (dimensionless)."""

    spec: SceneSpec
    mode: Literal["3d", "2d"]
    node_count: int
    dt: float                        # [s]
    gravity: np.ndarray              # (3,) [m/s^2]
    damping: float                   # [1/s], F_k = -damping * m_k * v_k
    integrator: Literal["backward_euler", "midpoint"]
    line_search: Literal["none", "backtrack", "auto"]
    newton_tol: float
    newton_dtol: float               # [m/s]
    newton_max_iter: int
    accept_unconverged: bool
    divergence_guard: float          # [-] residual growth factor that retries an accepted unconverged step; 0 off
    radius_max: float                # [m] the largest contact radius over the edges (non-circular sections: the
                                     # circumscribed radius); the step uses the per-edge edge_radius
    EA_max: float                    # [N]      the largest stiffnesses over the edges (all edges' for a uniform
    EI1_max: float                   # [N m^2]  rod; with per-edge radius or youngs_modulus lists, or several
    EI2_max: float                   # [N m^2]  rods, the largest): summaries only; the step uses the per-edge
    GJ_max: float                    # [N m^2]  and per-node values edge_EA and node_EI1/EI2/GJ
    rest_node_pos: np.ndarray        # (N, 3) [m] initial configuration (= rest, but for the edge lengths of a
                                     # pre-stretched rod: rest_edge_length)
    rest_edge_length: np.ndarray     # (N-1,) [m]
    voronoi_length: np.ndarray       # (N,) [m]
    node_mass: np.ndarray            # (N,) [kg]
    edge_twist_inertia: np.ndarray   # (N-1,) [kg m^2] = rho J lbar_j  ([REC])
    rest_ref_d1: np.ndarray          # (N-1, 3) initial space-parallel reference director
    rest_tangent: np.ndarray         # (N-1, 3)
    edge_radius: np.ndarray          # (N-1,) [m] contact radius per edge
    edge_EA: np.ndarray              # (N-1,) [N] stretching stiffness per edge
    node_EI1: np.ndarray             # (N,) [N m^2] bending stiffness at a node (interior: §1.5, compliance mean)
    node_EI2: np.ndarray             # (N,) [N m^2]
    node_GJ: np.ndarray              # (N,) [N m^2] twisting stiffness at a node (same rule)
    rest_kappa_bar: np.ndarray       # (N, 2) integrated natural curvature of the rest shape (rows 0, N-1 = 0)
    rest_tau_bar: np.ndarray         # (N,) natural twist of the rest shape [rad]
    dof_mass: np.ndarray             # (ndof,) [kg] or [kg m^2]
    dof_fixed: np.ndarray            # (ndof,) bool, constrained DOFs (identity rows)
    dof_gravity: np.ndarray          # (ndof,) [N] gravity force m_k g
    planar_component: int            # 2-D: which 3-D curvature component is in-plane (0: κ1, 1: κ2)
    planar_sign: float               # 2-D: κ_2D = planar_sign * κ_component
    plane_y: float                   # 2-D: the y of the motion plane [m]
    locked_edges: tuple[int, ...]
    obstacles: ObstacleGeometry  # kinds, sizes, meshes, spec poses (the poses per env are in the State)
    # point loads and prescribed motion (sim.scene.boundary, docs/physics.md §3.1, §3.6): per load / moving fix, its
    # per-DOF force [N, N m] or rate [m/s, rad/s] (K, ndof) and its time window [start, stop) (K, 2) [s]
    load_force: np.ndarray = field(default_factory=lambda: _ro(np.zeros((0, 0))))
    load_window: np.ndarray = field(default_factory=lambda: _ro(np.zeros((0, 2))))
    motion_rate: np.ndarray = field(default_factory=lambda: _ro(np.zeros((0, 0))))
    motion_window: np.ndarray = field(default_factory=lambda: _ro(np.zeros((0, 2))))
    # fixes turning rigidly at an angular velocity (rotating clamps), applied by the Simulator before each step
    rotating_fixes: tuple[RotatingFix, ...] = ()
    # the point loads that depend on the configuration (moments, material-frame loads), evaluated each step
    frame_loads: FrameLoads | None = None
    # several rods (docs/physics.md §1.7): the rods' names in file order, where each rod's nodes start in the
    # chain (R+1,) (the last entry N), and which edges are material (N-1,) (False: a joint edge between two rods)
    rod_names: tuple[str, ...] = ("rod",)
    rod_node_offsets: np.ndarray = field(default_factory=lambda: _ro(np.zeros(0, np.int64)))
    edge_link: np.ndarray = field(default_factory=lambda: _ro(np.zeros(0, bool)))
    # 2-D: each rod's (planar_component, planar_sign) (the first rod's are planar_component / planar_sign)
    rod_planar: tuple[tuple[int, float], ...] = ()

    @property
    def edge_count(self) -> int:
        return self.node_count - 1

    @property
    def dofs_per_node(self) -> int:
        return 4 if self.mode == "3d" else 2

    @property
    def rod_count(self) -> int:
        return len(self.rod_names)

    def rod_slices(self) -> dict[str, slice]:
        """name -> slice of the rod's nodes in the chain (its edges: ``slice(start, stop - 1)``), file order."""
        off = self.rod_node_offsets
        if len(off) != len(self.rod_names) + 1:  # a model built without the per-rod fields: one rod
            return {self.rod_names[0]: slice(0, self.node_count)}
        return {name: slice(int(off[k]), int(off[k + 1])) for k, name in enumerate(self.rod_names)}

    def split_rods(self, arr, axis: int = -2) -> dict[str, np.ndarray]:
        """name -> the rod's part of ``arr``, an array over the chain's nodes along ``axis`` (default -2: e.g.
        ``state.node_pos`` (B, N, 3) or the (frames, B, N, 3) ``node_pos`` of ``rodlab sim --out``). Views."""
        a = np.asarray(arr)
        ax = axis % a.ndim
        if a.shape[ax] != self.node_count:
            raise ValueError(f"split_rods: axis {axis} has length {a.shape[ax]}, not the node count {self.node_count}")
        idx = [slice(None)] * a.ndim
        out = {}
        for name, sl in self.rod_slices().items():
            idx[ax] = sl
            out[name] = a[tuple(idx)]
        return out


def _node_stiffness(edge: np.ndarray, lbar: np.ndarray) -> np.ndarray:
    """(N,) per-node bending or twisting stiffness from an (N-1,) per-edge one (docs/physics.md §1.5). An interior
    node's Voronoi cell is half of each adjacent edge, so its compliance is the mean of the two edges' compliances
    weighted by the half-edge lengths: ``K_i = (l̄_{i-1} + l̄_i) / (l̄_{i-1}/K_{i-1} + l̄_i/K_i)`` (the plain
    harmonic mean for equal edges; exactly the edges' value where they are equal, 0 where either is 0). An end
    node takes its edge's value (bending and twisting act at interior nodes only)."""
    out = np.empty(edge.shape[0] + 1)
    out[0] = edge[0]
    out[-1] = edge[-1]
    a, b = edge[:-1], edge[1:]
    la, lb = lbar[:-1], lbar[1:]
    same = a == b
    soft = (a == 0.0) | (b == 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        harm = (la + lb) / (la / a + lb / b)
    out[1:-1] = np.where(same, a, np.where(soft, 0.0, harm))
    return out


def _planar_axes(d1_0: np.ndarray, t_0: np.ndarray) -> tuple[int, float]:
    """(component, sign) of a planar rod's in-plane curvature from its first edge's reference frame
    (docs/physics.md §1.6): κb = -κ_2D ŷ, κ1 = -κ_2D (m2·ŷ), κ2 = κ_2D (m1·ŷ)."""
    d2_0 = np.cross(t_0, d1_0)
    if abs(d2_0[1]) > 0.5:
        return 0, float(-np.sign(d2_0[1]))
    return 1, float(np.sign(d1_0[1]) or 1.0)


def _rod_arrays(rod) -> dict:
    """The per-edge / per-node arrays of one rod (its own nodes and edges only)."""
    N = rod.nodes
    if getattr(rod, "rest_points", None) is not None:  # non-straight rest shape (docs/physics.md §1.2)
        x = np.array(rod.rest_points, dtype=np.float64).reshape(N, 3)
    else:
        d = np.asarray(rod.direction, dtype=np.float64)
        s = np.linspace(0.0, rod.length, N)
        x = np.asarray(rod.start, dtype=np.float64)[None, :] + s[:, None] * d[None, :]
    # rest edge lengths: the initial ones, or shorter by the pre-stretch ε0 (the rod starts stretched by ε0)
    lbar = np.linalg.norm(np.diff(x, axis=0), axis=1)
    eps0 = float(getattr(rod, "prestretch", 0.0))
    if eps0 != 0.0:
        lbar = lbar / (1.0 + eps0)
    vor = np.empty(N)
    vor[0] = 0.5 * lbar[0]
    vor[-1] = 0.5 * lbar[-1]
    vor[1:-1] = 0.5 * (lbar[:-1] + lbar[1:])
    # per-edge section and material (docs/physics.md §1.5): the scalar keys, or the per-edge lists
    er = getattr(rod, "edge_radius", None)
    eE = getattr(rod, "edge_youngs_modulus", None)
    E = np.full(N - 1, float(rod.youngs_modulus)) if eE is None else np.asarray(eE, dtype=np.float64)
    G = E / (2.0 * (1.0 + rod.poisson_ratio))
    if getattr(rod, "cross_section", "circle") == "circle":
        r = np.full(N - 1, float(rod.radius)) if er is None else np.asarray(er, dtype=np.float64)
        A = math.pi * r * r
        Jp = math.pi * r ** 4 / 2.0
        EI1 = EI2 = E * math.pi * r ** 4 / 4.0
        GJ = G * Jp
    else:  # sim/scene/section.py: I1, I2 about the directors, torsion constant J, polar moment; contact radius
        sec = section_of(rod)
        r, A, Jp = np.full(N - 1, sec.contact_radius), np.full(N - 1, sec.area), np.full(N - 1, sec.polar)
        EI1, EI2, GJ = E * sec.I1, E * sec.I2, G * sec.J
    if np.all(A == A[0]):  # one section: node mass ρ A l_vor
        mass = rod.density * A[0] * vor
    else:  # half of each adjacent edge's mass ρ A_j l_j
        me = rod.density * A * lbar
        mass = np.zeros(N)
        mass[:-1] += 0.5 * me
        mass[1:] += 0.5 * me
    d1, t = initial_reference_frames(x)
    kbar = material_curvature(x, d1, np.cross(t, d1))  # rest shape: material = reference frame (θ = 0)
    if getattr(rod, "natural_curvature", None) is not None:  # added to the rest shape's (its ends unused)
        kbar[1:-1] += np.asarray(rod.natural_curvature, dtype=np.float64).reshape(N, 2)[1:-1]
    return dict(
        x=x, lbar=lbar, vor=vor, r=r, EA=E * A, EI1=EI1, EI2=EI2, GJ=GJ, mass=mass, theta=rod.density * Jp * lbar,
        node_EI1=_node_stiffness(EI1, lbar), node_EI2=_node_stiffness(EI2, lbar), node_GJ=_node_stiffness(GJ, lbar),
        d1=d1, t=t,
        kbar=kbar,
        planar=_planar_axes(d1[0], t[0]))


def _built_in_edges(spec: SceneSpec, offsets: np.ndarray) -> list[int]:
    """The chain's edges at whose free ends the rod is built in exactly (docs/physics.md §3.6): the first edge of each
    rod with ``clamp = "node"`` and the edges held whole by a ``[[fix]]`` with ``built_in``."""
    edges = [int(off) for rod, off in zip(spec.rods, offsets[:-1]) if rod.clamp == "node"]
    planar = spec.sim.mode == "2d"
    for fx in spec.fixes:
        if fx.built_in:
            off, n = rod_span(spec, fx.rod)
            edges += [off + j for j in held_edges(fx, n, planar)]
    return edges


def _build_in(edges: list[int], fixed: np.ndarray, link: np.ndarray, lbar: np.ndarray, vor: np.ndarray,
              node_k: tuple[np.ndarray, ...], edge_k: tuple[np.ndarray, ...]) -> None:
    """Build the rod in at the free ends of the held ``edges`` (in place): a node between a held edge and a free
    material edge bends and twists over the free half of its cell only, with that edge's stiffnesses (``node_k``
    the (N,) node stiffnesses, ``edge_k`` the chain's (N-1,) edge stiffnesses in the same order)."""
    N = vor.shape[0]
    whole = fixed[:, :3].all(axis=1) if fixed.shape[1] == 4 else fixed.all(axis=1)
    held = whole[:-1] & whole[1:] & (fixed[:-1, 3] if fixed.shape[1] == 4 else True)
    for j in edges:
        for k, o in ((j, j - 1), (j + 1, j + 1)):
            if 0 < k < N - 1 and link[j] and link[o] and not held[o]:
                vor[k] = 0.5 * lbar[o]
                for nk, ek in zip(node_k, edge_k):
                    nk[k] = ek[o]


def _chain(parts: list[dict], key: str, joint) -> np.ndarray:
    """The rods' per-edge arrays ``key`` joined into the chain's, ``joint(a, b)`` the value of the joint edge
    between rods a and b (one rod: its own array)."""
    if len(parts) == 1:
        return parts[0][key]
    out = [parts[0][key]]
    for a, b in zip(parts[:-1], parts[1:]):
        out += [np.asarray(joint(a, b))[None], b[key]]
    return np.concatenate(out)


def build_model(spec: SceneSpec, *, locked_edges: Sequence[int] = ()) -> Model:
    """Build the Model of ``spec``.

    ``locked_edges``: extra edges j whose nodes x_j, x_{j+1} and twist angle θ^j are constrained (kept at the
    values the State holds; set ``state.dof[:, j, 3]`` to impose a twist angle). Used e.g. by the pure-twist
    check; ``rod.clamp = "first_edge"`` or ``"node"`` locks edge 0 the same way (each rod's first edge in a scene of
    several).

    Several rods (docs/physics.md §1.7) are one chain of nodes in file order; the edge between the last node of
    one rod and the first of the next is a joint edge (``edge_link`` False) that carries no material: no
    stretching, no mass, no bending or twisting at its end nodes, its twist angle fixed. Its per-edge entries hold
    finite placeholders (rest length 1, EA 0, twist inertia 1, the smaller radius of its two neighbours, the
    frame of the edge before it).
    """
    check_scene(spec)  # specs built in code get the scene file's checks (sim/scene/validate.py)
    sim = spec.sim
    parts = [_rod_arrays(rod) for rod in spec.rods]
    counts = [rod.nodes for rod in spec.rods]
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    N = int(offsets[-1])
    cat = (lambda key: parts[0][key]) if len(parts) == 1 else (lambda key: np.concatenate([p[key] for p in parts]))
    x = cat("x")
    vor, mass, kbar = cat("vor"), cat("mass"), cat("kbar")
    node_EI1, node_EI2, node_GJ = cat("node_EI1"), cat("node_EI2"), cat("node_GJ")
    lbar = _chain(parts, "lbar", lambda a, b: 1.0)
    r = _chain(parts, "r", lambda a, b: min(a["r"][-1], b["r"][0]))
    EA = _chain(parts, "EA", lambda a, b: 0.0)
    theta_inertia = _chain(parts, "theta", lambda a, b: 1.0)
    d1 = _chain(parts, "d1", lambda a, b: a["d1"][-1])
    t = _chain(parts, "t", lambda a, b: a["t"][-1])
    link = np.ones(N - 1, dtype=bool)
    link[offsets[1:-1] - 1] = False  # the joint edges: from each rod's last node to the next rod's first
    EI1 = np.concatenate([np.atleast_1d(p["EI1"]) for p in parts])
    EI2 = np.concatenate([np.atleast_1d(p["EI2"]) for p in parts])
    GJ = np.concatenate([np.atleast_1d(p["GJ"]) for p in parts])
    g = np.asarray(sim.gravity, dtype=np.float64)
    locked = set(int(j) for j in locked_edges)
    for j in locked:
        if not 0 <= j < N - 1:
            raise ValueError(f"locked_edges: edge index {j} out of range [0, {N - 2}]")
    for rod, off in zip(spec.rods, offsets[:-1]):
        if rod.clamp in ("first_edge", "node"):
            locked.add(int(off))
    # in-plane component for 2-D (docs/physics.md §1.6), of the first rod (rod_planar: each rod's)
    pc, ps = parts[0]["planar"]
    if sim.mode == "3d":
        ndn = 4
        dmass = np.empty((N, 4))
        dmass[:, :3] = mass[:, None]
        dmass[:-1, 3] = theta_inertia
        dmass[-1, 3] = 1.0
        fixed = np.zeros((N, 4), dtype=bool)
        fixed[-1, 3] = True
        fixed[:-1, 3] |= ~link  # the twist of a joint edge: fixed, like the dummy θ of the last node
        for j in locked:
            fixed[j, :3] = True
            fixed[j + 1, :3] = True
            fixed[j, 3] = True
        grav = np.zeros((N, 4))
        grav[:, :3] = mass[:, None] * g[None, :]
    else:
        ndn = 2
        dmass = np.repeat(mass[:, None], 2, axis=1)
        fixed = np.zeros((N, 2), dtype=bool)
        for j in locked:
            fixed[j, :] = True
            fixed[j + 1, :] = True
        grav = mass[:, None] * g[None, [0, 2]]
    fixed_dofs(spec, fixed)
    built_in = _built_in_edges(spec, offsets)
    if built_in:
        vor = vor.copy()
        node_EI1, node_EI2, node_GJ = node_EI1.copy(), node_EI2.copy(), node_GJ.copy()
        _build_in(built_in, fixed, link, lbar, vor, (node_EI1, node_EI2, node_GJ),
                  tuple(_chain(parts, key, lambda a, b: 0.0) for key in ("EI1", "EI2", "GJ")))
    lf, lw = load_arrays(spec, N, ndn, vor)
    fl = frame_load_arrays(spec)
    mr, mw = motion_arrays(spec, N, ndn)
    return Model(
        spec=spec, mode=sim.mode, node_count=N, dt=sim.dt, gravity=_ro(g), damping=sim.damping,
        integrator=sim.integrator, line_search=sim.line_search, newton_tol=sim.newton_tol,
        newton_dtol=sim.newton_dtol, newton_max_iter=sim.newton_max_iter, divergence_guard=sim.divergence_guard,
        accept_unconverged=sim.accept_unconverged, radius_max=float(r.max()), EA_max=float(EA.max()),
        EI1_max=float(EI1.max()), EI2_max=float(EI2.max()), GJ_max=float(GJ.max()), edge_radius=_ro(r), edge_EA=_ro(EA),
        node_EI1=_ro(node_EI1), node_EI2=_ro(node_EI2), node_GJ=_ro(node_GJ),
        rest_node_pos=_ro(x), rest_edge_length=_ro(lbar), voronoi_length=_ro(vor), node_mass=_ro(mass),
        edge_twist_inertia=_ro(theta_inertia), rest_ref_d1=_ro(d1), rest_tangent=_ro(t),
        rest_kappa_bar=_ro(kbar), rest_tau_bar=_ro(np.zeros(N)), dof_mass=_ro(dmass.ravel()),
        dof_fixed=_ro(fixed.ravel()), dof_gravity=_ro(grav.ravel()), planar_component=pc, planar_sign=ps,
        plane_y=float(x[0, 1]), locked_edges=tuple(sorted(locked)),
        obstacles=ObstacleGeometry.from_specs(spec.obstacles), load_force=_ro(lf), load_window=_ro(lw),
        motion_rate=_ro(mr), motion_window=_ro(mw), rotating_fixes=rotating_fixes(spec, x),
        frame_loads=fl if fl.count else None,
        rod_names=tuple(spec.rod_names),
        rod_node_offsets=_ro(offsets), edge_link=_ro(link), rod_planar=tuple(p["planar"] for p in parts),
    )


def planar_nodes(m: Model) -> tuple[np.ndarray, np.ndarray]:
    """(N,) per node: the planar component (0: κ1, 1: κ2) and sign of its rod (2-D, docs/physics.md §1.6)."""
    per_rod = getattr(m, "rod_planar", ()) or ((m.planar_component, m.planar_sign),)
    off = np.asarray(getattr(m, "rod_node_offsets", ()), dtype=np.int64)
    if len(off) != len(per_rod) + 1:
        off = np.array([0, m.node_count])
    counts = np.diff(off)
    comp = np.repeat(np.array([c for c, _ in per_rod], np.int64), counts)
    sign = np.repeat(np.array([sg for _, sg in per_rod], np.float64), counts)
    return comp, sign
