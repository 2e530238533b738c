"""Simulator: reset(), step(), control helpers. ``step`` is a short pipeline: check the inputs → the batched
kernel (per env: predict → Newton (frames, assemble, solve, line search) → contact refresh → accept/retry →
integrate → commit; :mod:`sim.kernels`) → StepStats. The kernels' data is built by
:meth:`sim.kernels.data.Params.from_model` and :meth:`sim.kernels.data.RodData.from_model`."""
from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np

from sim.analysis.internal import InternalLoads, internal_loads
from sim.contact.edge_pairs import model_pairs
from sim.contact.world import (
    PAIR_REPORT_CAPACITY,
    ObstacleWorld,
    contact_data,
    contact_scratch,
    set_active,
    set_capsules,
    set_pose,
)
from sim.geometry.frames import transport_vectors
from sim.kernels.batch import CHUNK, step_kernel
from sim.kernels.data import (
    MIDPOINT_ENERGY_TOL,
    ContactReport,
    ControlArrays,
    Params,
    RodData,
    StateArrays,
    StepOutput,
    alike,
)
from sim.scene import validate as _validate
from sim.scene.boundary import frame_load_forces, turn_fix, window_fraction
from sim.scene.model import Model, planar_nodes
from sim.state import STATE_ARRAYS, Control, State, StepStats

__all__ = ["Simulator", "MIDPOINT_ENERGY_TOL"]

IndexLike = int | Sequence[int] | np.ndarray | slice | None


class Simulator:
    """Batched implicit DER simulator for ``envs`` copies of ``model``.

    ``step(state, ctrl)`` advances ``state`` in place by ``model.dt`` and returns :class:`StepStats`. The
    Simulator holds only constants and work space; everything per env (obstacle poses included) is in the
    :class:`State`, as plain arrays (``state.obstacle_position`` …; :meth:`set_obstacle_pose`,
    :meth:`set_capsules`, :meth:`set_obstacle_active`).
    """

    def __init__(self, model: Model, envs: int = 1) -> None:
        if not isinstance(envs, (int, np.integer)) or envs < 1:
            raise ValueError(f"envs must be a positive integer, got {envs!r}")
        self.model = model
        self.envs = B = int(envs)
        m = model
        pairs = model_pairs(m)  # edge pairs that may touch (self- / rod–rod contact); (0, 2) without
        self._prm = Params.from_model(m, pairs=pairs).record()  # one typed record (passed by reference)
        self._rod = RodData.from_model(m, pairs=pairs)
        # point loads (sim.scene.boundary): per-env external forces only when a scene has loads; prescribed motion
        self._loads = m.load_force.shape[0] > 0
        self._frame_loads = m.frame_loads  # moments and material-frame loads: evaluated at each step's start
        self._motion = m.motion_rate.shape[0] > 0 or bool(m.rotating_fixes)
        moving = np.any(m.motion_rate != 0.0, axis=0) if m.motion_rate.shape[0] else np.zeros(m.dof_fixed.size, bool)
        dpn = m.dofs_per_node
        for rf in m.rotating_fixes:
            moving.reshape(-1, dpn)[rf.nodes, :3 if dpn == 4 else 2] = True
            if dpn == 4:
                moving.reshape(-1, dpn)[rf.edges, 3] = True
        self._moving_dofs = np.flatnonzero(moving) if self._motion else None
        # work space of the contact kernels (candidate lists) and the obstacles' world arrays, derived from the
        # poses in the State before each step
        self._scratch = contact_scratch(B, m.node_count, m.obstacles.count, m.edge_radius)
        self._world = ObstacleWorld(m.obstacles, B)
        C = int(m.obstacles.report_capacity) + (PAIR_REPORT_CAPACITY if pairs.shape[0] > 0 else 0)
        self._crep = ContactReport.zeros(B, C)
        # the most rows a step can list: every obstacle candidate, two per edge pair (StepStats rows grow up to it)
        self._max_rows = max(C, m.node_count * m.obstacles.count + 2 * pairs.shape[0])
        self._out = StepOutput.zeros(B)

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
                     **m.obstacles.initial_arrays(B), plane_y=m.plane_y if m.mode == "2d" else 0.0)

    def _rest_control_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        m = self.model
        kb = np.array(m.rest_kappa_bar)
        if m.mode == "2d":
            # column 0: the in-plane curvature in the first rod's convention (the kernel's κ_2D = planar_sign ·
            # column 0); a rod whose own component or sign differs has its value converted
            comp, sign = planar_nodes(m)
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
        a (B,) boolean mask, or integer env indices (list/tuple/int array/int); see :func:`sim.scene.validate.env_mask`."""
        mask = _validate.env_mask(mask, self.envs)
        fresh = self.reset()
        for name in STATE_ARRAYS:  # the obstacles' poses among them
            getattr(state, name)[mask] = getattr(fresh, name)[mask]
        if ctrl is not None:
            kb, tb = self._rest_control_arrays()
            ctrl.kappa_bar[mask] = kb
            ctrl.tau_bar[mask] = tb

    # ------------------------------------------------------------------ kernel data
    @property
    def kernel_params(self) -> np.ndarray:
        """The kernels' parameter record (``sim.kernels.data.Params``, a one-element structured array: flags and
        numbers of the step), built from the Model; read by the static solver, inverse statics and derivatives."""
        return self._prm

    @property
    def kernel_rod(self):
        """The kernels' rod record (``sim.kernels.data.RodData``: masses, stiffnesses, rest shape, fixed DOFs,
        gravity), built from the Model."""
        return self._rod

    def set_env_models(self, models: Sequence[Model]) -> None:
        """Give env e the masses, stiffnesses, damping and gravity of ``models[e]`` (one per env; each the model of
        the same rods as this one with other material values, section sizes, damping or gravity — several parameter
        sets stepped in one batch, as a multi-start fit does). Their initial state and controls are the caller's
        (:meth:`reset` stays this model's). ValueError naming what differs where the kernels share it (the rest
        shape, fixes, joints, the step's parameters, the contact's radii or settings)."""
        if len(models) != self.envs:
            raise ValueError(f"set_env_models: expected {self.envs} models (one per env), got {len(models)}")
        prm = self._prm[0]
        touching = int(prm["n_obstacles"]) > 0 or bool(prm["rod_pairs"])
        pairs = self._rod.pairs
        # the midpoint rule's energy floor scales with the stiffness (a threshold on rounding: the first's serves);
        # the motion plane is a 2-D rod's only
        skip = ("midpoint_energy_floor",) + (() if prm["planar"] else ("plane_y",))
        rods = []
        for e, m in enumerate(models):
            if m.mode != self.model.mode or m.node_count != self.model.node_count:
                raise ValueError(f"set_env_models: model {e} has {m.node_count} nodes in {m.mode}; this simulator's "
                                 f"has {self.model.node_count} in {self.model.mode}")
            p = Params.from_model(m, pairs=pairs).record()[0]
            bad = [name for name in p.dtype.names if name not in skip and not alike(p[name], prm[name])]
            if bad:
                raise ValueError(f"set_env_models: model {e} differs in the step parameter {bad[0]}, which every env "
                                 "shares")
            r = RodData.from_model(m, pairs=pairs)
            if not touching:  # the contact radii are read by contact only
                r = r._replace(edge_radius=self._rod.edge_radius)
            rods.append(r)
        try:
            self._rod = RodData.stacked(rods)
        except ValueError as exc:
            raise ValueError(f"set_env_models: {exc}") from None

    # ------------------------------------------------------------------ obstacle poses (in the State)
    def set_obstacle_pose(self, state: State, i: int, position, orientation_wxyz=(1.0, 0.0, 0.0, 0.0), *,
                          envs: IndexLike = None) -> None:
        """Obstacle ``i``'s pose in ``state``: ``position`` (3,) or (k, 3) [m], ``orientation_wxyz`` (4,) or (k, 4)
        (normalised), for ``envs`` (default all; indices or a (B,) mask); the next step sees it."""
        set_pose(self.model.obstacles, state, i, position, orientation_wxyz, envs=envs)

    def set_capsules(self, state: State, env_ids, starts, ends, radius, *, obstacle_ids=None) -> None:
        """Re-place capsule obstacles of envs ``env_ids`` in ``state``: ``starts``/``ends`` (k, m, 3) [m] world end
        points of the m capsules ``obstacle_ids`` (default: all capsules, in scene order), ``radius`` [m]."""
        set_capsules(self.model.obstacles, state, env_ids, starts, ends, radius, obstacle_ids=obstacle_ids)

    def set_obstacle_active(self, state: State, i: int, active: bool, *, envs: IndexLike = None) -> None:
        """Enable or disable obstacle ``i`` in ``state`` for ``envs`` (a disabled obstacle costs nothing)."""
        set_active(self.model.obstacles, state, i, active, envs=envs)

    def contact_data(self, state: State):
        """The contact kernels' view of ``state``'s obstacles (world arrays derived from its poses) with this
        Simulator's work space (:func:`sim.contact.world.contact_data`)."""
        return contact_data(self.model.obstacles, self._world.update(state), state, self._scratch)

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

    @property
    def has_contact(self) -> bool:
        """Whether the scene's steps compute any contact (obstacles with contact on, or edge pairs that may touch)."""
        prm = self._prm[0]
        return int(prm["n_obstacles"]) > 0 or bool(prm["rod_pairs"])

    # ------------------------------------------------------------------ stepping
    def _check(self, state: State, ctrl: Control) -> None:
        _validate.check_step_inputs(self, state, ctrl)  # every field named (sim/scene/validate.py)
        self._bad_in = _validate.quarantine_nonfinite(self, state)  # NaN/inf state: env failed, rest state

    def step(self, state: State, ctrl: Control) -> StepStats:
        """Advance every non-failed env of ``state`` by ``model.dt`` (in place) under ``ctrl``."""
        self._check(state, ctrl)
        cd = self.contact_data(state)
        rod = self._rod
        if self._loads or self._frame_loads is not None or ctrl.force is not None:
            rod = rod._replace(grav=self._external_forces(state.time, ctrl.force, state))
        moved = self._prescribe(state) if self._motion else None
        # the kernel's parallel loop runs over chunks of CHUNK envs: more threads than chunks would only wake threads
        # with nothing to do (one env would keep two cores busy), so the call uses at most one thread per chunk
        threads = numba.get_num_threads()
        use = min(threads, -(-self.envs // CHUNK))
        if use < threads:
            numba.set_num_threads(use)
        try:
            step_kernel(StateArrays.of(state), ControlArrays.of(ctrl), rod, self._prm, cd, self._crep, self._out)
        finally:
            if use < threads:
                numba.set_num_threads(threads)
        if moved is not None:  # the moved DOFs' velocities: their prescribed rates over the step
            ok = ~state.failed
            vel = state.dof_vel.reshape(self.envs, -1)
            sel = self._moving_dofs
            vel[np.ix_(ok, sel)] = moved[np.ix_(ok, sel)] / self.model.dt
        stats = self._checked_stats(state)
        self._grow_report()
        return stats

    def _grow_report(self) -> None:
        """Rows dropped in the step just taken (StepStats.contact_dropped says how many): the next steps list up to
        twice as many, at most every contact the scene can have."""
        cr = self._crep
        C = cr.gap.shape[1]
        if C < self._max_rows and cr.dropped.any():
            need = C + int(cr.dropped.max())
            self._crep = ContactReport.zeros(self.envs, min(self._max_rows, max(2 * C, need)))

    def _external_forces(self, time: np.ndarray, force: np.ndarray | None = None,
                         state: State | None = None) -> np.ndarray:
        """(B, n) gravity plus the point and line loads, each weighted by the fraction of the env's step in its
        window, plus the moments and material-frame loads at the configuration of ``state`` (the step's start;
        sim.scene.boundary.frame_load_forces), plus the control's node forces ``force`` (B, N, 3) [N] (in 2-D its x and z
        components)."""
        m = self.model
        grav = self._rod.grav
        if self._loads:
            grav = grav + window_fraction(time, m.dt, m.load_window) @ m.load_force
        fl = self._frame_loads
        if fl is not None:
            if state is None:
                raise ValueError("moments and material-frame loads need the state they act on")
            grav = grav + frame_load_forces(fl, window_fraction(time, m.dt, fl.window), state.node_pos,
                                            lambda: self.material_frames(state), 4 if m.mode == "3d" else 2)
        if force is not None:
            node = np.zeros((self.envs, m.node_count, 4 if m.mode == "3d" else 2))
            if m.mode == "3d":
                node[:, :, :3] = force
            else:
                node[:, :, 0], node[:, :, 1] = force[:, :, 0], force[:, :, 2]
            grav = grav + node.reshape(self.envs, -1)
        # a new writeable array, typed as the model's own gravity row (a broadcast view is read-only: numba would
        # compile the step kernel once more for it)
        out = np.empty((self.envs, grav.shape[-1]))
        out[...] = grav
        return out

    def _prescribe(self, state: State) -> np.ndarray:
        """Move the prescribed DOFs of every non-failed env to their values at the step end (the kernel keeps
        constrained DOFs where the State holds them); returns the (B, n) displacement."""
        m = self.model
        dof = state.dof.reshape(self.envs, -1)
        if m.motion_rate.shape[0]:
            disp = (window_fraction(state.time, m.dt, m.motion_window) * m.dt) @ m.motion_rate
            disp[state.failed] = 0.0
            dof += disp
        else:
            disp = np.zeros_like(dof)
        if m.rotating_fixes:  # rotating clamps: a rigid turn of their nodes and edges (sim.scene.boundary.turn_fix)
            before = dof.copy()
            seconds = window_fraction(state.time, m.dt, np.stack([rf.window for rf in m.rotating_fixes])) * m.dt
            for b in np.flatnonzero(~state.failed):
                for k, rf in enumerate(m.rotating_fixes):
                    if seconds[b, k] > 0.0:
                        turn_fix(rf, state.dof[b], state.edge_tangent[b], state.edge_ref_d1[b], float(seconds[b, k]),
                                 transport_vectors)
            disp += dof - before
        return disp

    def _checked_stats(self, state: State) -> StepStats:
        stats = self._stats()
        _validate.quarantine_nonfinite(self, state, stats, self._bad_in)  # no NaN leaves a step (sim/scene/validate.py)
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
            contact_gap=cr.gap.copy(), contact_dropped=cr.dropped.copy(), contact_force=cr.force.copy())

    # ------------------------------------------------------------------ frames
    def internal_loads(self, state: State, ctrl: Control) -> InternalLoads:
        """Axial force, bending and twisting moments of every env (``sim.analysis.internal.InternalLoads``, docs/physics.md
        §2.5) at the end of the last step, under the natural curvature and twist of ``ctrl``."""
        m1, m2, _t = self.material_frames(state)
        return internal_loads(self.model, state.node_pos, m1, m2, ctrl.kappa_bar, ctrl.tau_bar)

    def material_frames(self, state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(m1, m2, t), each (B, N-1, 3): material directors and unit tangents at the end of the last step."""
        t = state.edge_tangent
        d1 = state.edge_ref_d1
        d2 = np.cross(t, d1)
        th = state.edge_theta[..., None]
        c, s = np.cos(th), np.sin(th)
        return c * d1 + s * d2, -s * d1 + c * d2, t.copy()


def _ix(i: IndexLike):
    return slice(None) if i is None else i
