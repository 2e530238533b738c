"""Simulator: reset(), step(), control helpers. ``step`` is a short pipeline: check the inputs → the batched
kernel (per env: predict → Newton (frames, assemble, solve, line search) → contact refresh → accept/retry →
integrate → commit; :mod:`sim.newton`, :mod:`sim.kernel`) → StepStats."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from . import solve as _solve
from . import validate as _validate
from .boundary import window_fraction
from .contact_rod import model_pairs
from .contact_set import PAIR_REPORT_CAPACITY, contact_data, contact_radii, contact_scratch
from .model import Model
from .state import Control, State, StepStats

__all__ = ["Simulator", "MIDPOINT_ENERGY_TOL"]

# an implicit-midpoint (sub)step whose energy rises by more than this fraction is redone by backward Euler
MIDPOINT_ENERGY_TOL = 1e-3

IndexLike = int | Sequence[int] | np.ndarray | slice | None


class Simulator:
    """Batched implicit DER simulator for ``envs`` copies of ``model``.

    ``step(state, ctrl)`` advances ``state`` in place by ``model.dt`` and returns :class:`StepStats`. The
    Simulator holds only constants and work space; everything per env (obstacle poses included) is in the
    :class:`State`.
    """

    def __init__(self, model: Model, envs: int = 1) -> None:
        if not isinstance(envs, (int, np.integer)) or envs < 1:
            raise ValueError(f"envs must be a positive integer, got {envs!r}")
        self.model = model
        self.envs = B = int(envs)
        m = model
        c = m.spec.contact
        mp = getattr(c, "max_penetration", None)  # penetration guard [m]; None = 4 * delta
        # the planar rod bends with EI1 (kernel): there, the stiffness of its in-plane component (each rod's)
        if m.mode == "3d":
            ei1 = m.node_EI1
        else:
            comp, _ = _planar_nodes(m)
            ei1 = np.where(comp == 0, m.node_EI1, m.node_EI2)
        pairs = model_pairs(m)  # edge pairs that may touch (self- / rod–rod contact); (0, 2) without
        prm = _solve.Params(
            dt=m.dt, damping=m.damping, newton_tol=m.newton_tol,
            newton_dtol=m.newton_dtol, newton_max_iter=float(m.newton_max_iter),
            accept_unconverged=1.0 if m.accept_unconverged else 0.0,
            midpoint=0.0 if m.integrator == "backward_euler" else 1.0,
            line_search={"none": 0.0, "backtrack": 1.0, "auto": 2.0}[m.line_search],
            contact_k=c.stiffness, contact_delta=c.delta, friction=c.friction, friction_nu=c.friction_velocity_tol,
            friction_on=1.0 if np.any(m.obstacles.effective_friction(c.friction) > 0) else 0.0,
            contact_margin=c.margin, n_obstacles=float(m.obstacles.count if getattr(c, "enabled", True) else 0),
            planar_sign=m.planar_sign, plane_y=m.plane_y, retry_levels=5.0, max_strain=0.9,
            max_penetration=4.0 * c.delta if mp is None else float(mp),
            step_limit=1.0 if getattr(c, "step_limit", True) else 0.0, divergence_guard=m.divergence_guard,
            midpoint_energy_tol=MIDPOINT_ENERGY_TOL, planar=1.0 if m.mode == "2d" else 0.0,
            rod_pairs=1.0 if pairs.shape[0] > 0 else 0.0)
        self._prm = _solve.params_record(prm)  # one float64 record (passed by reference in the kernels)
        self._rod = _solve.RodData(rest_len=np.array(m.rest_edge_length), vor_len=np.array(m.voronoi_length),
                                   mass=np.array(m.dof_mass), fixed=np.array(m.dof_fixed),
                                   grav=np.array(m.dof_gravity)[None, :], EA=np.array(m.edge_EA),
                                   EI1=np.array(ei1), EI2=np.array(m.node_EI2), GJ=np.array(m.node_GJ),
                                   radius=contact_radii(m.edge_radius), link=_edge_link(m), pairs=pairs)
        # point loads (sim.boundary): per-env external forces only when a scene has loads; prescribed motion
        self._loads = m.load_force.shape[0] > 0
        self._motion = m.motion_rate.shape[0] > 0
        self._moving_dofs = np.flatnonzero(np.any(m.motion_rate != 0.0, axis=0)) if self._motion else None
        # work space of the contact kernels (candidate lists); the poses themselves are in State.obstacles
        self._scratch = contact_scratch(B, m.node_count, m.obstacles.count, m.edge_radius)
        self._no_obstacles = m.obstacles.for_envs(B) if m.obstacles.count == 0 else None
        C = int(m.obstacles.report_capacity) + (PAIR_REPORT_CAPACITY if pairs.shape[0] > 0 else 0)
        self._crep = _solve.ContactReport(
            count=np.zeros(B, np.int64), edge=np.zeros((B, C), np.int64), obstacle=np.zeros((B, C), np.int64),
            partner=np.full((B, C), -1, np.int64),
            rod_point=np.zeros((B, C, 3)), obstacle_point=np.zeros((B, C, 3)), normal=np.zeros((B, C, 3)),
            normal_force=np.zeros((B, C)), friction_force=np.zeros((B, C, 3)), gap=np.zeros((B, C)),
            max_penetration=np.zeros(B))
        f, i = (lambda: np.zeros(B)), (lambda: np.zeros(B, np.int64))
        self._out = _solve.StepOutput(
            residual=f(), residual0=f(), energy_stretch=f(), energy_bend=f(), energy_twist=f(), energy_contact=f(),
            energy_kinetic=f(), energy_gravity=f(), newton_iters=i(), substeps=i(), midpoint_fallbacks=i(),
            converged=np.zeros(B, bool), failed=np.zeros(B, bool))

    # ------------------------------------------------------------------ state / control construction
    def _rest_dof(self) -> np.ndarray:
        m = self.model
        x = m.rest_node_pos
        if m.mode == "3d":
            q = np.zeros((m.node_count, 4))
            q[:, :3] = x
        else:
            q = x[:, [0, 2]].copy()
        return q

    def reset(self) -> State:
        """State of all envs at the rest configuration, at rest, time 0."""
        B, m = self.envs, self.model
        q0 = self._rest_dof()
        q = np.broadcast_to(q0, (B,) + q0.shape).copy()
        return State(dof=q, dof_vel=np.zeros_like(q),
                     edge_ref_d1=np.broadcast_to(m.rest_ref_d1, (B, m.node_count - 1, 3)).copy(),
                     edge_tangent=np.broadcast_to(m.rest_tangent, (B, m.node_count - 1, 3)).copy(),
                     node_ref_twist=np.zeros((B, m.node_count)), time=np.zeros(B), failed=np.zeros(B, bool),
                     plane_y=m.plane_y if m.mode == "2d" else 0.0, obstacles=m.obstacles.for_envs(B))

    def _rest_control_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        m = self.model
        kb = np.array(m.rest_kappa_bar)
        if m.mode == "2d":
            # column 0: the in-plane curvature in the first rod's convention (the kernel's κ_2D = planar_sign ·
            # column 0); a rod whose own component or sign differs has its value converted
            comp, sign = _planar_nodes(m)
            kb0 = np.where(comp == 0, kb[:, 0], kb[:, 1]) * (sign * m.planar_sign)
            kb = np.stack([kb0, np.zeros(m.node_count)], axis=1)
        return kb, np.array(m.rest_tau_bar)

    def make_control(self) -> Control:
        """Control with the rest natural curvature/twist for every env."""
        kb, tb = self._rest_control_arrays()
        B = self.envs
        return Control(kappa_bar=np.broadcast_to(kb, (B,) + kb.shape).copy(),
                       tau_bar=np.broadcast_to(tb, (B,) + tb.shape).copy())

    def reset_envs(self, state: State, ctrl: Control | None, mask: np.ndarray) -> None:
        """Reset the envs selected by ``mask`` to rest (state, the obstacles' spec poses and, if given, control):
        a (B,) boolean mask, or integer env indices (list/tuple/int array/int); see :func:`sim.validate.env_mask`."""
        mask = _validate.env_mask(mask, self.envs)
        fresh = self.reset()
        for name in ("dof", "dof_vel", "edge_ref_d1", "edge_tangent", "node_ref_twist", "time", "failed"):
            getattr(state, name)[mask] = getattr(fresh, name)[mask]
        if state.obstacles is not None and state.obstacles.count:
            state.obstacles.reset_envs(mask)
        if ctrl is not None:
            kb, tb = self._rest_control_arrays()
            ctrl.kappa_bar[mask] = kb
            ctrl.tau_bar[mask] = tb

    # ------------------------------------------------------------------ control helpers
    def set_natural_curvature(self, ctrl: Control, value, *, nodes: IndexLike = None, envs: IndexLike = None) -> None:
        """ctrl.kappa_bar[envs, nodes, :] = value (broadcast; integrated curvature, dimensionless)."""
        ctrl.kappa_bar[_ix(envs), _ix(nodes)] = value

    def add_natural_curvature(self, ctrl: Control, delta, *, nodes: IndexLike = None, envs: IndexLike = None) -> None:
        """ctrl.kappa_bar[envs, nodes, :] += delta; takes effect in the next ``step``."""
        ctrl.kappa_bar[_ix(envs), _ix(nodes)] += delta

    def set_natural_twist(self, ctrl: Control, value, *, nodes: IndexLike = None, envs: IndexLike = None) -> None:
        """ctrl.tau_bar[envs, nodes] = value [rad]."""
        ctrl.tau_bar[_ix(envs), _ix(nodes)] = value

    def add_natural_twist(self, ctrl: Control, delta, *, nodes: IndexLike = None, envs: IndexLike = None) -> None:
        """ctrl.tau_bar[envs, nodes] += delta [rad]."""
        ctrl.tau_bar[_ix(envs), _ix(nodes)] += delta

    # ------------------------------------------------------------------ stepping
    def _check(self, state: State, ctrl: Control) -> None:
        _validate.check_step_inputs(self, state, ctrl)  # every field named (sim/validate.py)
        self._bad_in = _validate.quarantine_nonfinite(self, state)  # NaN/inf state: env failed, rest state

    def step(self, state: State, ctrl: Control) -> StepStats:
        """Advance every non-failed env of ``state`` by ``model.dt`` (in place) under ``ctrl``."""
        self._check(state, ctrl)
        obstacles = self._no_obstacles if state.obstacles is None else state.obstacles
        rod = self._rod
        if self._loads:
            rod = rod._replace(grav=self._external_forces(state.time))
        moved = self._prescribe(state) if self._motion else None
        _solve.step_kernel(
            _solve.StateArrays(dof=state.dof.reshape(self.envs, -1), vel=state.dof_vel.reshape(self.envs, -1),
                               ref_d1=state.edge_ref_d1, tangent=state.edge_tangent, ref_twist=state.node_ref_twist,
                               time=state.time, failed=state.failed),
            _solve.ControlArrays(kappa_bar=np.ascontiguousarray(ctrl.kappa_bar, dtype=np.float64),
                                 tau_bar=np.ascontiguousarray(ctrl.tau_bar, dtype=np.float64)),
            rod, self._prm, contact_data(obstacles, self._scratch), self._crep, self._out)
        if moved is not None:  # the moved DOFs' velocities: their prescribed rates over the step
            ok = ~state.failed
            vel = state.dof_vel.reshape(self.envs, -1)
            sel = self._moving_dofs
            vel[np.ix_(ok, sel)] = moved[np.ix_(ok, sel)] / self.model.dt
        return self._checked_stats(state)

    def _external_forces(self, time: np.ndarray) -> np.ndarray:
        """(B, n) gravity plus the point loads, each weighted by the fraction of the env's step in its window."""
        m = self.model
        frac = window_fraction(time, m.dt, m.load_window)
        return np.ascontiguousarray(self._rod.grav + frac @ m.load_force)

    def _prescribe(self, state: State) -> np.ndarray:
        """Move the prescribed DOFs of every non-failed env to their values at the step end (the kernel keeps
        constrained DOFs where the State holds them); returns the (B, n) displacement."""
        m = self.model
        disp = (window_fraction(state.time, m.dt, m.motion_window) * m.dt) @ m.motion_rate
        disp[state.failed] = 0.0
        state.dof.reshape(self.envs, -1)[...] += disp
        return disp

    def _checked_stats(self, state: State) -> StepStats:
        stats = self._stats()
        _validate.quarantine_nonfinite(self, state, stats, self._bad_in)  # no NaN leaves a step (sim/validate.py)
        return stats

    def _stats(self) -> StepStats:
        o, cr = self._out, self._crep
        return StepStats(
            newton_iters=o.newton_iters.copy(), residual=o.residual.copy(), residual0=o.residual0.copy(),
            converged=o.converged.copy(), substeps=o.substeps.copy(), midpoint_fallbacks=o.midpoint_fallbacks.copy(),
            failed=o.failed.copy(),
            energy_stretch=o.energy_stretch.copy(), energy_bend=o.energy_bend.copy(),
            energy_twist=o.energy_twist.copy(), energy_contact=o.energy_contact.copy(),
            energy_kinetic=o.energy_kinetic.copy(), energy_gravity=o.energy_gravity.copy(),
            max_penetration=cr.max_penetration.copy(), contact_count=cr.count.copy(), contact_edge=cr.edge.copy(),
            contact_obstacle=cr.obstacle.copy(), contact_partner_edge=cr.partner.copy(),
            contact_rod_point=cr.rod_point.copy(),
            contact_obstacle_point=cr.obstacle_point.copy(), contact_normal=cr.normal.copy(),
            contact_normal_force=cr.normal_force.copy(), contact_friction_force=cr.friction_force.copy(),
            contact_gap=cr.gap.copy())

    # ------------------------------------------------------------------ frames
    def material_frames(self, state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(m1, m2, t), each (B, N-1, 3): material directors and unit tangents at the end of the last step."""
        t = state.edge_tangent
        d1 = state.edge_ref_d1
        d2 = np.cross(t, d1)
        th = state.edge_theta[..., None]
        c, s = np.cos(th), np.sin(th)
        return c * d1 + s * d2, -s * d1 + c * d2, t.copy()


def _edge_link(m: Model) -> np.ndarray:
    """The kernels' (N-1,) uint8 edge flags: 1 a material edge, 0 a joint edge between two rods."""
    link = getattr(m, "edge_link", None)
    if link is None or len(link) != m.node_count - 1:
        return np.ones(m.node_count - 1, np.uint8)
    return np.asarray(link, dtype=np.uint8)


def _planar_nodes(m: Model) -> tuple[np.ndarray, np.ndarray]:
    """(N,) per node: the planar component (0: κ1, 1: κ2) and sign of its rod (2-D, docs/physics.md §1.6)."""
    per_rod = getattr(m, "rod_planar", ()) or ((m.planar_component, m.planar_sign),)
    off = np.asarray(getattr(m, "rod_node_offsets", ()), dtype=np.int64)
    if len(off) != len(per_rod) + 1:
        off = np.array([0, m.node_count])
    counts = np.diff(off)
    comp = np.repeat(np.array([c for c, _ in per_rod], np.int64), counts)
    sign = np.repeat(np.array([sg for _, sg in per_rod], np.float64), counts)
    return comp, sign


def _ix(i: IndexLike):
    return slice(None) if i is None else i
