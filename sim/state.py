"""State, Control and StepStats: struct-of-arrays with a leading env axis B (shapes and SI units below)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.scene.validate import state_arrays

__all__ = ["State", "Control", "StepStats", "STATE_ARRAYS", "STATE_FLOAT_ARRAYS"]


@dataclass(eq=False)
class State:
    """Dynamic state of B envs (N nodes).

    dof            (B, N, 4) 3-D [x, y, z, θ] (m, rad; θ of edge j at node j, last θ a dummy = 0)
                   or (B, N, 2) 2-D [x, z] (m)
    dof_vel        same shape, (q_new − q_old)/h of the last (sub)step (m/s, rad/s)
    edge_ref_d1    (B, N-1, 3) reference director d1 at the end of the last step (unit)
    edge_tangent   (B, N-1, 3) unit tangent at the end of the last step
    node_ref_twist (B, N) reference twist β [rad] (0 at both end nodes)
    time           (B,) [s]
    failed         (B,) bool, env failed irrecoverably and is frozen until reset
    obstacle_position    (B, M, 3) [m] each obstacle's position (boxes, meshes, cylinders: their frame's origin)
    obstacle_orientation (B, M, 4) its orientation, a unit quaternion wxyz
    obstacle_a, obstacle_b (B, M, 3) [m] local geometry: capsule ends, sphere centre (a), plane point / normal
    obstacle_radius      (B, M) [m] capsule, sphere and cylinder radius
    obstacle_active      (B, M) bool, False: the obstacle is ignored in that env
    plane_y        2-D only: y of the motion plane [m] (used by node_pos)

    The obstacles' geometry (kinds, meshes, sizes) is the Model's (``model.obstacles``); their poses are these
    arrays, written directly or with ``Simulator.set_obstacle_pose`` / ``set_capsules`` / ``set_obstacle_active``
    (docs/physics.md §4). ``copy()`` is a full snapshot and ``assign(other)`` copies one into this state's arrays;
    ``node_pos``/``node_vel``/``edge_theta`` are new arrays.
    """

    dof: np.ndarray
    dof_vel: np.ndarray
    edge_ref_d1: np.ndarray
    edge_tangent: np.ndarray
    node_ref_twist: np.ndarray
    time: np.ndarray
    failed: np.ndarray
    obstacle_position: np.ndarray
    obstacle_orientation: np.ndarray
    obstacle_a: np.ndarray
    obstacle_b: np.ndarray
    obstacle_radius: np.ndarray
    obstacle_active: np.ndarray
    plane_y: float = 0.0

    @property
    def env_count(self) -> int:
        return self.dof.shape[0]

    @property
    def is_2d(self) -> bool:
        return self.dof.shape[-1] == 2

    def _xyz(self, a: np.ndarray, fill: float) -> np.ndarray:
        if not self.is_2d:
            return a[..., :3].copy()
        out = np.empty(a.shape[:-1] + (3,))
        out[..., 0] = a[..., 0]
        out[..., 1] = fill
        out[..., 2] = a[..., 1]
        return out

    @property
    def node_pos(self) -> np.ndarray:
        """(B, N, 3) node positions [m] (a new array; the state is changed through ``dof``)."""
        return self._xyz(self.dof, self.plane_y)

    @property
    def node_vel(self) -> np.ndarray:
        """(B, N, 3) node velocities [m/s]."""
        return self._xyz(self.dof_vel, 0.0)

    @property
    def edge_theta(self) -> np.ndarray:
        """(B, N-1) twist angles θ [rad] (zeros in 2-D)."""
        if self.is_2d:
            return np.zeros(self.dof.shape[:2])[:, :-1]
        return self.dof[:, :-1, 3].copy()

    def copy(self) -> "State":
        return State(**{name: getattr(self, name).copy() for name in STATE_ARRAYS}, plane_y=self.plane_y)

    def assign(self, other: "State") -> None:
        """Copy ``other`` (a state of the same scene and env count) into this state's arrays, in place."""
        for name in STATE_ARRAYS:
            dst, src = getattr(self, name), getattr(other, name)
            if dst.shape != src.shape:
                raise ValueError(f"State.assign: {name} has shape {src.shape}, this state's is {dst.shape}")
            dst[...] = src
        self.plane_y = other.plane_y


# The per-env arrays of a State (leading axis B), in field order: the fields typed np.ndarray (plane_y is not a
# per-env array), read from the dataclass by sim.scene.validate.state_arrays; copies, input checks, quarantine, static
# restores and the fuzz benchmark go through it.
STATE_ARRAYS: tuple[str, ...] = state_arrays(State)
# the float ones (all but the bool ``failed`` and ``obstacle_active``)
STATE_FLOAT_ARRAYS: tuple[str, ...] = tuple(name for name in STATE_ARRAYS if name not in ("failed", "obstacle_active"))


@dataclass(eq=False)
class Control:
    """Per-env natural curvature/twist (the parameters the step reads).

    kappa_bar (B, N, 2) integrated natural curvature [κ̄1, κ̄2] at nodes (dimensionless; rows 0, N-1 unused).
              2-D mode: only kappa_bar[..., 0] is used; it is the 3-D component that is in-plane for the
              rod's direction (κ1 for a +z rod), see docs/conventions.md.
    tau_bar   (B, N) integrated natural twist [rad] at nodes (rows 0, N-1 unused; ignored in 2-D).
    force     (B, N, 3) point forces [N] on the nodes during the step, world axes (in 2-D the y component is
              ignored), or None: a hand pulling the rod, a disturbance. They add to gravity and the scene's loads as
              external forces held over the step (docs/physics.md §3.1); energy_gravity then holds their potential too.
    """

    kappa_bar: np.ndarray
    tau_bar: np.ndarray
    force: np.ndarray | None = None

    def copy(self) -> "Control":
        return Control(self.kappa_bar.copy(), self.tau_bar.copy(), None if self.force is None else self.force.copy())


@dataclass(eq=False)
class StepStats:
    """Per-env results of one ``Simulator.step`` (leading axis B; C = contact report capacity).

    newton_iters (B,) int (total over sub-steps), residual (B,) last evaluated ‖f‖ [mixed N, N·m],
    residual0 (B,) first ‖f‖ of the step, converged (B,) bool, substeps (B,) int (1 = no retry),
    midpoint_fallbacks (B,) int (with ``integrator = "midpoint"``: how many of the step's sub-steps gained energy and
    were redone by backward Euler, docs/physics.md §3.3; always 0 with backward Euler),
    failed (B,) bool (failed in this step), energy_* (B,) [J] at the end of the step, max_penetration (B,) [m]
    (the deepest obstacle contact or edge pair), contact_* rows (docs/architecture.md): the obstacle contacts, then
    two rows per edge pair in touch (self- or rod–rod contact), one per edge with the force on it;
    contact_obstacle is −1 on a pair row and contact_partner_edge the other edge (−1 on an obstacle row). Over every
    contact, listed or not: contact_dropped (B,) int the rows that did not fit the report (the Simulator then grows
    it for the next steps), contact_force (B, 3) [N] the total contact force (normal plus friction) on the rods.
    """

    newton_iters: np.ndarray
    residual: np.ndarray
    residual0: np.ndarray
    converged: np.ndarray
    substeps: np.ndarray
    failed: np.ndarray
    energy_stretch: np.ndarray
    energy_bend: np.ndarray
    energy_twist: np.ndarray
    energy_contact: np.ndarray
    energy_kinetic: np.ndarray
    energy_gravity: np.ndarray
    max_penetration: np.ndarray
    contact_count: np.ndarray
    contact_edge: np.ndarray
    contact_obstacle: np.ndarray
    contact_partner_edge: np.ndarray
    contact_rod_point: np.ndarray
    contact_obstacle_point: np.ndarray
    contact_normal: np.ndarray
    contact_normal_force: np.ndarray
    contact_friction_force: np.ndarray
    contact_gap: np.ndarray
    midpoint_fallbacks: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    contact_dropped: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    contact_force: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def energy_elastic(self) -> np.ndarray:
        return self.energy_stretch + self.energy_bend + self.energy_twist

    @property
    def energy_total(self) -> np.ndarray:
        """Elastic + contact + kinetic + gravity potential [J]."""
        return self.energy_elastic + self.energy_contact + self.energy_kinetic + self.energy_gravity
