"""The named data the step kernels exchange, each built from the Model where it is defined.

:class:`Params` is the solver's scalar parameters, typed (floats, counts, flags and the :class:`LineSearch` enum)
and passed to the kernels as one record of :data:`PARAMS_DTYPE` (read as ``prm``); :class:`RodData` the rod's
constant arrays; :class:`StateArrays` / :class:`ControlArrays` the batched state and control the kernel advances
and reads; :class:`StepOutput` / :class:`ContactReport` the per-env columns it writes for StepStats. Also the
(sub)step status codes and the Jacobian's half bandwidths. The per-thread scratch is in :mod:`sim.kernels.workspace`.
"""
from __future__ import annotations

import dataclasses
from enum import IntEnum
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from sim.contact.edge_pairs import model_pairs, pair_links
from sim.contact.world import contact_radii
from sim.numba_options import OPT_ALLOC
from sim.scene.model import planar_nodes

__all__ = ["LineSearch", "Params", "PARAMS_DTYPE", "RodData", "StateArrays", "ControlArrays", "StepOutput",
           "ContactReport", "OK", "NON_FINITE", "RESIDUAL_GROWTH", "BAD_PIVOT", "UNCONVERGED", "STRAIN",
           "MIDPOINT_GAINED", "KL_3D", "KL_2D", "MIDPOINT_ENERGY_TOL", "MIDPOINT_ENERGY_FLOOR", "RETRY_LEVELS",
           "MAX_STRAIN", "env_rod", "alike"]

# (sub)step status codes of sim.kernels.newton
OK, NON_FINITE, RESIDUAL_GROWTH, BAD_PIVOT, UNCONVERGED, STRAIN, MIDPOINT_GAINED = range(7)

KL_3D = 10  # half bandwidth of the 3-D Jacobian (a bend-twist element spans 11 DOFs)
KL_2D = 5  # half bandwidth of the 2-D Jacobian (a bend element spans 6 DOFs)

# an implicit-midpoint (sub)step whose energy rises by more than this fraction is redone by backward Euler
MIDPOINT_ENERGY_TOL = 1e-3
# ... and by more than this many times the rod's bending scale EI/L [J] (the energy of bending the longest rod by a
# radian): a gain below it is the rounding of energies near 0, not the midpoint rule's instability
MIDPOINT_ENERGY_FLOOR = 1e-12
RETRY_LEVELS = 5  # retry levels of the step (level k: 2^k sub-steps; docs/physics.md §6)
MAX_STRAIN = 0.9  # a (sub)step that leaves an edge strained beyond this |ε| fails


def _bending_scale(m: Any) -> float:
    """EI/L [J] of the stiffest bending of the longest rod of model ``m``: the energy of bending it by a radian."""
    length = max(float(r.length) for r in m.spec.rods)
    return max(float(m.EI1_max), float(m.EI2_max)) / length


class LineSearch(IntEnum):
    """``[sim] line_search``: none (full Newton steps), backtrack (every step), auto (lazily, only after an
    update raised ‖f‖ in an env with contact candidates)."""

    NONE = 0
    BACKTRACK = 1
    AUTO = 2


@dataclasses.dataclass(frozen=True)
class Params:
    """The solver's scalar parameters by name, read in the kernels as ``prm`` (one record of
    :data:`PARAMS_DTYPE`, :meth:`record`). Units: dt [s], newton_dtol [m/s],
    contact_delta/contact_margin/max_penetration/plane_y [m], contact_k [N/m], friction_nu [m/s]; the rest
    dimensionless; drag_normal/drag_tangential [N s/m²] and the flow velocity flow_x/y/z [m/s] of the viscous drag
    (``drag_on``: a coefficient above 0; docs/physics.md §3.1). ``planar``: the 2-D model; ``midpoint``: implicit
    midpoint, else backward Euler; ``friction_on``: some obstacle has friction; ``rod_pairs``: edges of rods may
    touch each other (self- or rod–rod contact on and allowed pairs exist, sim/contact/edge_pairs.py; they use
    contact_k, contact_delta, contact_margin and the [contact] friction μ = friction); ``n_obstacles``: 0 when contact is disabled."""

    dt: float
    newton_tol: float
    newton_dtol: float
    contact_k: float
    contact_delta: float
    friction: float
    friction_nu: float
    contact_margin: float
    planar_sign: float
    plane_y: float
    max_strain: float
    max_penetration: float
    divergence_guard: float
    midpoint_energy_tol: float
    midpoint_energy_floor: float
    drag_normal: float
    drag_tangential: float
    flow_x: float
    flow_y: float
    flow_z: float
    newton_max_iter: int
    n_obstacles: int
    retry_levels: int
    line_search: LineSearch
    accept_unconverged: bool
    midpoint: bool
    friction_on: bool
    step_limit: bool
    planar: bool
    rod_pairs: bool
    drag_on: bool

    @classmethod
    def from_model(cls, model: Any, *, pairs: np.ndarray | None = None) -> Params:
        """The parameters of ``model``'s step; ``pairs``: its edge pairs that may touch
        (:func:`sim.contact.edge_pairs.model_pairs`, computed when not given)."""
        m = model
        c = m.spec.contact
        mp = getattr(c, "max_penetration", None)  # penetration guard [m]; None = 4 * delta
        if pairs is None:
            pairs = model_pairs(m)
        drag = getattr(m.spec, "drag", None)
        flow = drag.flow if drag is not None else (0.0, 0.0, 0.0)
        return cls(
            dt=m.dt, newton_tol=m.newton_tol, newton_dtol=m.newton_dtol,
            contact_k=c.stiffness, contact_delta=c.delta, friction=c.friction, friction_nu=c.friction_velocity_tol,
            contact_margin=c.margin, planar_sign=m.planar_sign, plane_y=m.plane_y, max_strain=MAX_STRAIN,
            max_penetration=4.0 * c.delta if mp is None else float(mp), divergence_guard=m.divergence_guard,
            midpoint_energy_tol=MIDPOINT_ENERGY_TOL, midpoint_energy_floor=MIDPOINT_ENERGY_FLOOR * _bending_scale(m),
            newton_max_iter=int(m.newton_max_iter),
            drag_normal=drag.normal if drag is not None else 0.0,
            drag_tangential=drag.tangential if drag is not None else 0.0,
            flow_x=float(flow[0]), flow_y=float(flow[1]), flow_z=float(flow[2]),
            drag_on=drag is not None and drag.acts,
            n_obstacles=int(m.obstacles.count if getattr(c, "enabled", True) else 0), retry_levels=RETRY_LEVELS,
            line_search=LineSearch[m.line_search.upper()], accept_unconverged=bool(m.accept_unconverged),
            midpoint=m.integrator != "backward_euler",
            friction_on=bool(np.any(m.obstacles.effective_friction(c.friction) > 0)),
            step_limit=bool(getattr(c, "step_limit", True)), planar=m.mode == "2d", rod_pairs=pairs.shape[0] > 0)

    def record(self) -> np.ndarray:
        """The kernels' form: a one-element array of :data:`PARAMS_DTYPE` (the kernels read ``prm = prm_arr[0]``
        once per chunk of envs; numba passes a record by reference)."""
        arr = np.zeros(1, dtype=PARAMS_DTYPE)
        for f in dataclasses.fields(self):
            arr[0][f.name] = _FIELD_KINDS[f.type](getattr(self, f.name))
        return arr


# the record's field types: float64, int64 (counts and enums, stored as their int value), bool
_FIELD_KINDS = {"float": float, "int": int, "LineSearch": int, "bool": bool}
_DTYPES = {"float": np.float64, "int": np.int64, "LineSearch": np.int64, "bool": np.bool_}
PARAMS_DTYPE = np.dtype([(f.name, _DTYPES[f.type]) for f in dataclasses.fields(Params)], align=True)


class RodData(NamedTuple):
    """The rod's constant per-edge / per-node / per-DOF arrays (docs/physics.md §1.2): rest edge lengths (N-1,),
    Voronoi lengths (N,), fixed-DOF flags (n,) shared by every env, and per env (leading axis R: 1 shared by all
    envs, or B, one row per env, row min(e, R - 1) — :func:`env_rod` picks env e's): the DOF masses mass (R, n), the
    stiffnesses EA [N] per edge (R, N-1), EI1/EI2/GJ [N m²] per node (R, N) (an interior node: the length-weighted
    mean of its two edges' compliances; docs/physics.md §1.5) and the viscous damping rate damping (R, 1) [1/s]; the
    external forces grav (gravity plus point loads) (R, n) likewise, (B, n) when time-windowed loads act. The planar
    rod reads its in-plane bending stiffness from EI1. edge_radius [m]: the contact radius, (1,) for a rod of one
    radius, else (N-1,) per edge (sim.contact.imc). link (N-1,) uint8: 1 for a material edge, 0 for a joint edge
    between two rods of a scene (docs/physics.md §1.7): no stretching, no bending or twisting at its two nodes, no
    contact, its frame carried along unchanged. pairs (P, 2) int64: the edge pairs that may touch
    (sim.contact.edge_pairs.allowed_pairs; (0, 2) without self- or rod–rod contact); pair_links (P, 3) int64: the
    pairs sharing each pair's start nodes (sim.contact.edge_pairs.pair_links: which node terms a pair carries).

    The kernels of one env read the record :func:`env_rod` gives: its rows of the per-env arrays (mass (n,), EA,
    EI1, EI2, GJ, damping (1,)), the rest as here."""

    rest_len: np.ndarray
    vor_len: np.ndarray
    mass: np.ndarray
    fixed: np.ndarray
    grav: np.ndarray
    EA: np.ndarray
    EI1: np.ndarray
    EI2: np.ndarray
    GJ: np.ndarray
    edge_radius: np.ndarray
    link: np.ndarray
    pairs: np.ndarray
    pair_links: np.ndarray
    damping: np.ndarray

    @classmethod
    def from_model(cls, model: Any, *, pairs: np.ndarray | None = None) -> RodData:
        """The arrays of ``model``, one row shared by every env (gravity only in grav); ``pairs`` as in
        :meth:`Params.from_model`."""
        m = model
        if m.mode == "3d":
            ei1 = m.node_EI1
        else:  # the planar rod bends with EI1: there, the stiffness of its in-plane component (each rod's)
            comp, _ = planar_nodes(m)
            ei1 = np.where(comp == 0, m.node_EI1, m.node_EI2)
        if pairs is None:
            pairs = model_pairs(m)
        def row(a) -> np.ndarray:
            return np.array(a, dtype=np.float64)[None, :]

        return cls(rest_len=np.array(m.rest_edge_length), vor_len=np.array(m.voronoi_length),
                   mass=row(m.dof_mass), fixed=np.array(m.dof_fixed), grav=row(m.dof_gravity),
                   EA=row(m.edge_EA), EI1=row(ei1), EI2=row(m.node_EI2), GJ=row(m.node_GJ),
                   edge_radius=contact_radii(m.edge_radius), link=_edge_link(m),
                   pairs=pairs, pair_links=pair_links(pairs), damping=np.full((1, 1), float(m.damping)))

    PER_ENV = ("mass", "grav", "EA", "EI1", "EI2", "GJ", "damping")  # the fields with a row per env (or one)

    @classmethod
    def stacked(cls, rods: "list[RodData]") -> RodData:
        """One record of B envs from B one-row records of rods alike but for their per-env fields (:attr:`PER_ENV`:
        masses, stiffnesses, damping, external forces); the shared arrays are the first's. ValueError naming the
        field where they differ beyond rounding (rest lengths, fixed DOFs, joints, contact radii, edge pairs)."""
        first = rods[0]
        for name in cls._fields:
            if name in cls.PER_ENV:
                continue
            if not all(alike(getattr(first, name), getattr(r, name)) for r in rods[1:]):
                raise ValueError(f"the envs' rods differ in {name}, which every env shares")
        per = {name: np.ascontiguousarray(np.concatenate([getattr(r, name)[:1] for r in rods], axis=0))
               for name in cls.PER_ENV}
        return first._replace(**per)


def alike(a, b) -> bool:
    """Equal, or for floats equal to rounding (a rest shape moved as a whole keeps its lengths to the last bits)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return False
    if a.dtype.kind == "f":
        return bool(np.allclose(a, b, rtol=1e-12, atol=0.0))
    return bool(np.array_equal(a, b))


def _edge_link(m: Any) -> np.ndarray:
    """The kernels' (N-1,) uint8 edge flags: 1 a material edge, 0 a joint edge between two rods."""
    link = getattr(m, "edge_link", None)
    if link is None or len(link) != m.node_count - 1:
        return np.ones(m.node_count - 1, np.uint8)
    return np.asarray(link, dtype=np.uint8)


@njit(**OPT_ALLOC)  # with the runtime: the views it returns are counted in the caller (OPT's would be freed twice)
def env_rod(rod, e):
    """Env e's record of ``rod`` (:class:`RodData`): its rows of the per-env arrays (row min(e, R - 1))."""
    return RodData(rod.rest_len, rod.vor_len, rod.mass[min(e, rod.mass.shape[0] - 1)], rod.fixed, rod.grav,
                   rod.EA[min(e, rod.EA.shape[0] - 1)], rod.EI1[min(e, rod.EI1.shape[0] - 1)],
                   rod.EI2[min(e, rod.EI2.shape[0] - 1)], rod.GJ[min(e, rod.GJ.shape[0] - 1)], rod.edge_radius,
                   rod.link, rod.pairs, rod.pair_links, rod.damping[min(e, rod.damping.shape[0] - 1)])


class StateArrays(NamedTuple):
    """The batched state the kernel advances in place (leading axis B): DOFs and their velocities (B, n), the
    stored reference frames (B, N-1, 3) and reference twist (B, N), time (B,), failed flags (B,)."""

    dof: np.ndarray
    vel: np.ndarray
    ref_d1: np.ndarray
    tangent: np.ndarray
    ref_twist: np.ndarray
    time: np.ndarray
    failed: np.ndarray

    @classmethod
    def of(cls, state: Any) -> StateArrays:
        """Views of a :class:`sim.State`'s arrays (the kernel's writes reach the State)."""
        B = state.dof.shape[0]
        return cls(dof=state.dof.reshape(B, -1), vel=state.dof_vel.reshape(B, -1), ref_d1=state.edge_ref_d1,
                   tangent=state.edge_tangent, ref_twist=state.node_ref_twist, time=state.time, failed=state.failed)


class ControlArrays(NamedTuple):
    """The per-env natural curvature (B, N, 2) and twist (B, N) the step reads (twist unused in 2-D)."""

    kappa_bar: np.ndarray
    tau_bar: np.ndarray

    @classmethod
    def of(cls, ctrl: Any) -> ControlArrays:
        """A :class:`sim.Control`'s arrays as contiguous float64."""
        return cls(kappa_bar=np.ascontiguousarray(ctrl.kappa_bar, dtype=np.float64),
                   tau_bar=np.ascontiguousarray(ctrl.tau_bar, dtype=np.float64))


class StepOutput(NamedTuple):
    """What the step kernel writes per env for StepStats (all (B,)): the last and first residual ‖f‖ of the step,
    the energies [J] at its end, Newton iterations (total over sub-steps), sub-steps per step of the level
    accepted (1 = no retry), how many of those sub-steps the implicit midpoint rule redid by backward Euler (0 with
    backward Euler), whether every sub-step converged, whether the env failed in this step."""

    residual: np.ndarray
    residual0: np.ndarray
    energy_stretch: np.ndarray
    energy_bend: np.ndarray
    energy_twist: np.ndarray
    energy_contact: np.ndarray
    energy_kinetic: np.ndarray
    energy_gravity: np.ndarray
    newton_iters: np.ndarray
    substeps: np.ndarray
    midpoint_fallbacks: np.ndarray
    converged: np.ndarray
    failed: np.ndarray

    @classmethod
    def zeros(cls, envs: int) -> StepOutput:
        B = envs
        f, i = (lambda: np.zeros(B)), (lambda: np.zeros(B, np.int64))
        return cls(residual=f(), residual0=f(), energy_stretch=f(), energy_bend=f(), energy_twist=f(),
                   energy_contact=f(), energy_kinetic=f(), energy_gravity=f(), newton_iters=i(), substeps=i(),
                   midpoint_fallbacks=i(), converged=np.zeros(B, bool), failed=np.zeros(B, bool))


class ContactReport(NamedTuple):
    """The per-env contact rows the step kernels write for StepStats (leading axis B; C = report capacity):
    count (B,), edge/obstacle/partner (B, C) int64, rod_point/obstacle_point/normal/friction_force (B, C, 3),
    normal_force/gap (B, C), max_penetration (B,); obstacle rows first, then two rows per edge pair in touch. Over
    every contact, listed or not: dropped (B,) int64 the rows that did not fit the capacity, force (B, 3) [N] the total
    contact force (normal plus friction) on the rods (edge pairs add none: their two rows cancel)."""

    count: np.ndarray
    edge: np.ndarray
    obstacle: np.ndarray
    partner: np.ndarray
    rod_point: np.ndarray
    obstacle_point: np.ndarray
    normal: np.ndarray
    normal_force: np.ndarray
    friction_force: np.ndarray
    gap: np.ndarray
    max_penetration: np.ndarray
    dropped: np.ndarray
    force: np.ndarray

    @classmethod
    def zeros(cls, envs: int, capacity: int) -> ContactReport:
        B, C = envs, capacity
        return cls(count=np.zeros(B, np.int64), edge=np.zeros((B, C), np.int64), obstacle=np.zeros((B, C), np.int64),
                   partner=np.full((B, C), -1, np.int64), rod_point=np.zeros((B, C, 3)),
                   obstacle_point=np.zeros((B, C, 3)), normal=np.zeros((B, C, 3)), normal_force=np.zeros((B, C)),
                   friction_force=np.zeros((B, C, 3)), gap=np.zeros((B, C)), max_penetration=np.zeros(B),
                   dropped=np.zeros(B, np.int64), force=np.zeros((B, 3)))
