"""Derivatives of a rollout by the implicit function theorem (docs/physics.md §3.9).

A backward-Euler step solves f(x'; x, u, frames, κ̄, τ̄, θ) = 0 for the new DOFs x'. At the solution,
J δx' = −(∂f/∂s δs + ∂f/∂p δp), J = ∂f/∂x' the Newton Jacobian, s the step-start state, p the controls and
parameters; u' = (x' − x)/h. Chained over the steps this gives the tangent (forward) mode :meth:`Tape.jvp` and,
transposed, the adjoint (reverse) mode :meth:`Tape.vjp`.

* ∂f/∂p: the residual is affine in every parameter differentiated here (κ̄, τ̄, the stiffness scales, the mass
  scale, damping, gravity), so its column is the difference of two residual evaluations of the step's own
  element kernels, exact up to rounding (no step size).
* 3-D frames: the residual depends on the step-start reference frames only through one angle per edge (turning a
  reference director about its tangent is the same as turning the material frame, i.e. adding to θ). The state
  carried through the steps is (x, u, φ): φ the angle by which each edge's reference director is turned. Time-
  parallel transport adds φ' = φ + k·(δt + δt') per edge, k = (t' × t)/(1 + t·t') (the holonomy of the transport).
* J: exact in 2-D. In 3-D the Newton Jacobian moves the reference directors by zero-twist transport; its θ columns
  are kept and each bend–twist element's position block gains the exact terms of the transported directors' turn
  (sim.kernels.linearise). J stays banded; one banded LU, made in place, solves with J and with Jᵀ.

* Obstacle contact: its normal residual E'(g) ∇g depends on the new positions alone, so it enters J (the band,
  with each env's candidates over its step's motion); friction also depends on the start positions through the
  slip velocity (x' − x)/h, so with friction ∂f/∂x is a band of its own (central differences of the residual in
  the start positions) and J's position columns come from differences too (the Newton Jacobian leaves out how the
  lagged normal and closest point turn). The ownership rule and the candidate list are piecewise constant, so the
  derivative is that of the contact set the solution has.
* Contact between edges (self- and rod–rod): a pair couples DOFs far apart along the chain, so J = A + U E_Sᵀ, A the
  band without the pairs, S the free position DOFs of the nodes of the pairs within reach and U (n, s) their columns
  (central differences of the pairs' residual, step 1e-7 extrapolated: the energy turns over the contact distance);
  J⁻¹ and J⁻ᵀ by the Woodbury identity on A's banded factor (s extra columns and an s × s solve per env). With
  friction the pairs' slip velocity adds their start columns to ∂f/∂x. The pairs are those at the solution (found
  again there: the contact margin must be at least δ), with the terms each carries there.

The derivatives are of the backward-Euler map the Newton iterate satisfies; a step that ended unconverged
(``accept_unconverged``) is differentiated as if it had converged (:attr:`Tape.unconverged` counts them). A step
the retry ladder split into ns sub-steps in an env is differentiated sub-step by sub-step: the rollout takes them
again from the step's start with the ladder's own sub-step kernel (:func:`sim.kernels.probe.substeps_at`, bit for
bit) and records their states; each part j of the step is linearised in every env at once, the envs whose
sub-steps are over (or whose step was whole) left as they are by it (:class:`_Part`). The implicit midpoint rule is covered: its step solves a backward-Euler
residual over h/2 for the half-step point y = x½ and the end follows linearly, x' = 2 y − x, u' = 2 (y − x)/(h/2) − u
(the end frames transported from the start to x'); a midpoint step that gained energy and was redone by backward
Euler is differentiated as such, in its env alone. Prescribed motion (fixes moved at a velocity or twist rate, or
turned) is covered: the moved DOFs are constants of each step (held, their tangent 0), and each step is linearised
from the state its kernel started from, the motion already applied (the rollout applies the step's motion stage to
a copy to record it). Viscous drag is covered: it depends on the step's
start through the velocity and the tangent it lags, so with drag ∂f/∂x is a band, by differences as with friction.

Parameters (keys of the tangent / gradient dicts):

    dof0, vel0          (B, n)        the initial DOFs (3-D: the stored frames follow by parallel transport)
                                      and their velocities
    kappa_bar           (T, B, N, 2)  the natural curvature of every step (2-D: column 0)
    tau_bar             (T, B, N)     the natural twist of every step (3-D)
    force               (T, B, N, 3)  the point forces on the nodes of every step [N] (``Control.force``; 2-D: the
                                      y component does nothing): ∂f/∂F = −1 on the free position DOFs
    log_youngs_modulus  (B,)          ln of a factor on every stretching and bending stiffness
    log_shear_modulus   (B,)          ln of a factor on every twisting stiffness
    log_density         (B,)          ln of a factor on every mass (and weight)
    log_radius          (B,)          ln of a factor on every edge's radius (circular sections): the stretching
                                      stiffness and masses scale with its square, the bending and twisting
                                      stiffness and the twist angles' inertia with its fourth power, the contact
                                      radius with it
    damping             (B,)          the viscous damping rate [1/s]
    gravity             (B, 3)        the gravity vector [m/s²]
    log_contact_stiffness (B,)        ln of a factor on the [contact] stiffness (obstacle contact)
    log_contact_delta   (B,)          ln of a factor on the [contact] distance δ over which the energy acts
    friction            (B,)          the [contact] friction μ (of the obstacles without a μ of their own)
    obstacle_position   (B, M, 3)     each obstacle's position [m] (its local origin in the world)
    obstacle_rotation   (B, M, 3)     a small turn of each obstacle about its local origin, as a rotation vector in
                                      world axes [rad] (orientation' = exp(ω) ∘ orientation)

The radius enters every stiffness and mass as a power and the contact's gap: its column is a central difference of
the residual in its log factor (the rod record scaled as above, the weight with the mass), at the part's contact set.
The residual is linear in the contact stiffness (E ∝ k, and friction ∝ λ) and in μ, so their columns are
differences of two residual evaluations (the stiffness doubled; μ + 1), at the contact set of the step's solution;
without obstacle contact they are 0. The obstacles' poses (constant through a rollout) enter the contact residual
through their world arrays: their columns are central differences of the residual with the poses moved and the
world arrays derived anew (:func:`sim.contact.world.world_arrays`), at the contact set of the step's solution (with
friction at step 1e-7, extrapolated, as the start band).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from sim.analysis.local_maps import EdgeTurns, LocalColumns, band_columns
from sim.contact.world import ObstacleWorld, contact_data, contact_scratch, spec_contact_data, world_arrays
from sim.kernels.data import KL_2D, KL_3D, ControlArrays, StateArrays
from sim.kernels.linearise import (
    ELEMENT_ROWS,
    Linearisation,
    RodFactors,
    Wanted,
    factor_bands,
    linearise_step,
    solve_bands,
)
from sim.kernels.probe import assemble_at, pair_linearisation, pair_residual, substeps_at
from sim.state import STATE_ARRAYS, Control

__all__ = ["GradientError", "Tape", "rollout", "PARAMETERS"]

PARAMETERS = ("dof0", "vel0", "kappa_bar", "tau_bar", "force", "log_youngs_modulus", "log_shear_modulus", "log_density",
              "log_radius", "damping", "gravity", "log_contact_stiffness", "friction", "log_contact_delta", "obstacle_position",
              "obstacle_rotation")
_POSE_FIELDS = ("obstacle_position", "obstacle_rotation")
_CONTACT_FIELDS = ("log_contact_stiffness", "friction", "log_contact_delta")


class GradientError(ValueError):
    """A rollout or a request the derivatives do not cover, with what and where."""


def _dense(ab: np.ndarray, n: int, kl: int) -> np.ndarray:
    """The (..., n, n) matrices of full bands (..., n + kl, 2 kl + 1), ab[r, kl + c − r] = J[r, c]."""
    J = np.zeros(ab.shape[:-2] + (n, n))
    for d in range(2 * kl + 1):
        off = d - kl
        r = np.arange(max(0, -off), min(n, n - off))
        J[..., r, r + off] = ab[..., r, d]
    return J


_SCALARS = ("log_youngs_modulus", "log_shear_modulus", "log_density", "damping")
# Friction's law turns over a slip of |v_t| h (0.2 mm at 1 cm/s and dt = 0.02 s) and its sticking branch over
# ν h / 7.5 (3 µm at ν = 1e-3 m/s): central differences of step ε err by ≈ (ε / that)² / 6, so with friction they
# step 1e-7 (not 1e-6) of the coordinates and are extrapolated from ε and ε/2 (Richardson: the ε² term cancels)
FRICTION_FD_STEP = 1e-7
_CACHE_BYTES = 256 * 2**20  # linearisations kept for further passes while they fit in this


@dataclasses.dataclass(frozen=True)
class _Rule:
    """How each env's step end follows from the point its residual is solved for, y (``h_solve``: the step of that
    residual): x' = alpha y + beta x, u' = gamma (y − x) − delta u (constrained DOFs: u' = 0). Backward Euler: y = x',
    u' = (x' − x)/h. Implicit midpoint: y = x½ (a backward-Euler residual over h/2), x' = 2 x½ − x,
    u' = 2 (x½ − x)/(h/2) − u. Each field (B,): a midpoint step that gained energy was redone by backward Euler in
    its env alone."""

    h_solve: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    gamma: np.ndarray
    delta: np.ndarray
    identity: np.ndarray  # (B,) the envs this part leaves as they are: x' = x, u' = u (alpha 0, beta 1, gamma 0, delta −1)

    @classmethod
    def of(cls, h, midpoint: np.ndarray, identity: np.ndarray | None = None) -> "_Rule":
        """``h``: the step (a number, or one per env); ``midpoint`` (B,): the envs whose step was an
        implicit-midpoint step; ``identity`` (B,): the envs the part leaves as they are (their sub-steps are over)."""
        mp = np.asarray(midpoint, dtype=bool)
        same = np.zeros(mp.shape, bool) if identity is None else np.asarray(identity, dtype=bool)
        h = np.broadcast_to(np.asarray(h, dtype=np.float64), mp.shape)
        return cls(np.where(mp, 0.5 * h, h), np.where(same, 0.0, np.where(mp, 2.0, 1.0)),
                   np.where(same, 1.0, np.where(mp, -1.0, 0.0)), np.where(same, 0.0, np.where(mp, 4.0 / h, 1.0 / h)),
                   np.where(same, -1.0, np.where(mp, 1.0, 0.0)), same)

    @property
    def any_midpoint(self) -> bool:
        return bool(np.any(self.delta > 0.0))

    def solved(self, x: np.ndarray, x1: np.ndarray) -> np.ndarray:
        """The solved-for point y (B, n) from the step's start x and end x' (an env the part leaves: its x)."""
        alpha = np.where(self.identity, 1.0, self.alpha)[:, None]
        return np.where(self.identity[:, None], x, (x1 - self.beta[:, None] * x) / alpha)


@dataclasses.dataclass(frozen=True)
class _Part:
    """A part of recorded step ``k`` as its linearisation sees it, every field (B, …): the whole step, or where the
    retry ladder split it in some env, sub-step ``j`` (an env that took ns sub-steps has ns parts; the parts after
    an env's last are the identity for it, :attr:`_Rule.identity`). x0, u0, (d1, t0, b0): the DOFs, velocities and
    frames the part starts from (the step's prescribed motion applied); ``pre`` the DOFs before the motion (a change
    of the state before the step moves the frames as these); x1, t1: the DOFs and tangents it ends at."""

    k: int
    j: int
    x0: np.ndarray
    pre: np.ndarray
    u0: np.ndarray
    d1: np.ndarray
    t0: np.ndarray
    b0: np.ndarray
    x1: np.ndarray
    t1: np.ndarray
    rule: _Rule

    def solved(self) -> np.ndarray:
        """(B, n) the point the part's residual was solved for (its end; the midpoint rule: the half-step point)."""
        return self.rule.solved(self.x0, self.x1)


@dataclasses.dataclass
class _Lin:
    """All envs' step ``step`` linearised at its solution: J as padded bands (B, n + kl, 2 kl + 1) (the storage of
    :mod:`sim.kernels.banded`; constrained DOFs: identity rows and columns); the start-state columns Fx (B, n)
    (diagonal; with friction or drag a matrix (B, n, n)), Fu (B, n) (diagonal); frame maps G (n × E per env, ∂f/∂φ:
    :class:`LocalColumns`), a, b (E × n per env, φ' = φ + a δx + b δx': :class:`EdgeTurns`); parameter columns P
    (name -> (B, n, k) or :class:`LocalColumns`). J is factored (banded LU, in place) on the first solve; its
    factors serve solves with J and with Jᵀ."""

    step: int
    J: np.ndarray
    kl: int
    Fx: np.ndarray
    Fu: np.ndarray
    G: np.ndarray | None
    a: np.ndarray | None
    b: np.ndarray | None
    P: dict
    rule: "_Rule"
    a_end: np.ndarray | None = None  # the end frames' maps when the rule solves for another point than the end
    b_end: np.ndarray | None = None
    low: dict = dataclasses.field(default_factory=dict)  # env -> (S, U): edge pairs in touch, J = band + U E_Sᵀ
    Jc: np.ndarray | None = None  # (B, n, nc) J's columns of the constrained DOFs (before they were made identity)
    factored: bool = False  # J holds its LU factors (made on the first solve)
    _lu: dict = dataclasses.field(default_factory=dict, repr=False)  # the edge pairs' Woodbury terms per env

    def end_maps(self):
        """(a, b) of the step's end frames: φ' = φ + a δx + b δx'."""
        return (self.a, self.b) if self.a_end is None else (self.a_end, self.b_end)

    def start_term(self, dx: np.ndarray) -> np.ndarray:
        """Fx δx for every env: dx (B, n, Q)."""
        return self.Fx @ dx if self.Fx.ndim == 3 else self.Fx[:, :, None] * dx

    def start_adjoint(self, lam: np.ndarray) -> np.ndarray:
        """Fxᵀ λ for every env: lam (B, n)."""
        return np.einsum("bnm,bn->bm", self.Fx, lam) if self.Fx.ndim == 3 else self.Fx * lam

    def _factor(self) -> np.ndarray:
        """J's LU factors, made in place on the first solve (they serve J and Jᵀ)."""
        if not self.factored:
            status = np.zeros(self.J.shape[0], np.int64)
            factor_bands(self.J, self.kl, status)
            self.factored = True
            bad = np.flatnonzero(status)
            if bad.size:
                raise GradientError(f"step {self.step}: env {int(bad[0])}'s Jacobian is singular (pivot "
                                    f"{int(status[bad[0]]) - 1}); its derivative is not defined")
        return self.J

    def _woodbury(self, e: int, transpose: bool) -> tuple[np.ndarray, np.ndarray]:
        """For env e's edge-pair term J = A + U E_Sᵀ (A the band): (W, C) with W = A⁻¹ U and C = I + W[S] (or, for
        Jᵀ = Aᵀ + E_S Uᵀ, W = A⁻ᵀ E_S and C = I + Uᵀ W): then J⁻¹ b = z − W C⁻¹ z[S] (J⁻ᵀ b = z − W C⁻¹ Uᵀ z),
        z the band's solve (the Woodbury identity; s = |S| extra columns of the band's factor)."""
        key = ("woodbury", e, transpose)
        if key not in self._lu:
            S, U = self.low[e]
            n, s = U.shape
            if transpose:
                rhs = np.zeros((1, n, s))
                rhs[0, S, np.arange(s)] = 1.0
            else:
                rhs = U[None]
            W = np.empty((1, n, s))
            solve_bands(np.ascontiguousarray(self._factor()[e:e + 1]), self.kl, transpose, np.ascontiguousarray(rhs), W)
            W = W[0]
            self._lu[key] = (W, np.eye(s) + (U.T @ W if transpose else W[S]))
        return self._lu[key]

    def solve(self, rhs: np.ndarray, *, transpose: bool = False) -> np.ndarray:
        """J⁻¹ rhs or J⁻ᵀ rhs for every env: rhs (B, n, P)."""
        lu = self._factor()
        out = np.empty(rhs.shape)
        solve_bands(lu, self.kl, transpose, np.ascontiguousarray(rhs, dtype=np.float64), out)
        for e, (S, U) in self.low.items():
            W, C = self._woodbury(e, transpose)
            z = out[e]
            try:
                out[e] = z - W @ np.linalg.solve(C, U.T @ z if transpose else z[S])
            except np.linalg.LinAlgError:
                raise GradientError(f"step {self.step}: env {e}'s Jacobian with its edge-pair contact is singular; "
                                    "its derivative is not defined") from None
        return out

    @property
    def nbytes(self) -> int:
        arrays = [self.J, self.Fx, self.G, self.a, self.b, self.a_end, self.b_end, *self.P.values(),
                  *(a for v in self._lu.values() for a in v),
                  *(a for v in self.low.values() for a in v)]
        return sum(a.nbytes for a in arrays if a is not None)


@dataclasses.dataclass
class Tape:
    """A recorded rollout of ``T`` steps of B envs (see :func:`rollout`): the states before and after every step
    and the controls each step read. :attr:`unconverged` counts the steps (over envs) that ended unconverged."""

    sim: object
    dof: np.ndarray  # (T + 1, B, n)
    vel: np.ndarray  # (T + 1, B, n)
    ref_d1: np.ndarray  # (T + 1, B, E, 3)
    tangent: np.ndarray  # (T + 1, B, E, 3)
    ref_twist: np.ndarray  # (T + 1, B, N)
    kappa_bar: np.ndarray  # (T, B, N, 2)
    tau_bar: np.ndarray  # (T, B, N)
    grav: np.ndarray  # (T, B, n) the external forces (gravity and loads) of each step
    unconverged: int = 0
    moved: dict | None = None  # with prescribed motion: each step's start (dof, ref_d1, tangent, ref_twist (T, B, …)),
    # the motion applied (moved DOFs, turned clamp frames); None: the states before the steps
    fallback: np.ndarray | None = None  # (T, B) the midpoint steps redone by backward Euler
    subs: object = None  # per step {env: (ns, xs, vs, d1s, ts, bs, fell)}: the sub-steps of the envs the retry ladder
    # split (states before each and after the last, midpoint sub-steps redone by backward Euler); None: none split
    poses: dict | None = None  # the obstacles' pose arrays through the rollout (ObstacleWorld._POSE), with contact
    contact: object = None  # the obstacles' contact data of the rollout (its own work space), None without contact
    _lin: dict = dataclasses.field(default_factory=dict, repr=False)
    _replay: object = dataclasses.field(default=None, repr=False)  # a checkpointed rollout's records (rollout(checkpoint=))

    @property
    def nbytes(self) -> int:
        """Bytes the tape keeps of the rollout (records, checkpoints and controls; not the linearisations a pass
        keeps for the next one, at most 256 MiB)."""
        inputs = self.kappa_bar.nbytes + self.tau_bar.nbytes
        if self._replay is not None:
            return inputs + self._replay.nbytes
        arrays = [self.dof, self.vel, self.ref_d1, self.tangent, self.ref_twist, self.grav, self.fallback,
                  *(self.moved or {}).values(), *(a for step in self.subs or () for sub in step.values()
                                                   for a in sub[1:])]
        return inputs + sum(a.nbytes for a in arrays if a is not None)

    @property
    def steps(self) -> int:
        return self.kappa_bar.shape[0]

    def _start(self, k: int) -> np.ndarray:
        """(B, n) the DOFs step k started from: the state before it, with the prescribed DOFs already moved to their
        values at the step's end (the step moves them first and holds them there)."""
        return self.dof[k] if self.moved is None else self.moved["dof"][k]

    def _frames(self, k: int):
        """(ref_d1, tangent, ref_twist) step k started from (a turning clamp's frames turned first)."""
        if self.moved is None:
            return self.ref_d1[k], self.tangent[k], self.ref_twist[k]
        return self.moved["ref_d1"][k], self.moved["tangent"][k], self.moved["ref_twist"][k]

    # ------------------------------------------------------------------ linearisation of one step (all envs)
    def _rods(self, k: int):
        """The kernels' rod data of step k (each env's external forces; no DOF constrained) and its variants with
        the stiffness, twisting stiffness or mass doubled."""
        rod = self.sim.kernel_rod._replace(grav=np.ascontiguousarray(self.grav[k]))
        rod = rod._replace(fixed=np.zeros_like(rod.fixed))
        weight = self.sim.kernel_rod.grav  # the weights (R, n): the record's own external forces are gravity's
        rod_e = rod._replace(EA=2.0 * rod.EA, EI1=2.0 * rod.EI1, EI2=2.0 * rod.EI2)
        rod_g = rod._replace(GJ=2.0 * rod.GJ)
        rod_m = rod._replace(mass=2.0 * rod.mass, grav=np.ascontiguousarray(rod.grav + weight))
        return rod, rod_e, rod_g, rod_m

    @property
    def _cd(self):
        if self.contact is not None:
            return self.contact
        if "cd" not in self._lin:
            m = self.sim.model
            self._lin["cd"] = spec_contact_data(m.obstacles, 1, m.node_count, m.edge_radius, candidates=0)
        return self._lin["cd"]

    def _linear(self, k: int, names: tuple[str, ...], j: int = 0) -> _Lin:
        """Part j of step k linearised (:class:`_Part`), kept for further passes while they fit."""
        lin = self._lin.get((k, j))
        if lin is None or any(nm not in lin.P for nm in names if nm not in ("gravity", "force")):
            lin = self._linearise(self._part(k, j), names)
            kept = sum(v.nbytes for key, v in self._lin.items() if isinstance(key, tuple))
            if self._replay is None and kept + 2 * lin.nbytes < _CACHE_BYTES:  # room for it and its Woodbury terms
                self._lin[(k, j)] = lin
        return lin

    def _held_ok(self) -> bool:
        """Whether the constrained DOFs keep a change through the steps: yes unless a clamp is turned about a centre
        ([[fix]] angular_velocity: its DOFs' change turns with it)."""
        return not any(any(f.angular_velocity) for f in self.sim.model.spec.fixes)

    def _check_held(self) -> None:
        if not self._held_ok():
            raise GradientError("dof0: a change of the constrained DOFs (the clamp moved) with a clamp turned about a "
                                "centre ([[fix]] angular_velocity) is not available: a turned clamp's change turns")

    def _subs(self, k: int) -> dict:
        return {} if self.subs is None else self.subs[k]

    def parts(self, k: int) -> int:
        """How many parts step k is differentiated in: 1, or the most sub-steps the retry ladder split it into in an
        env."""
        return max((v[0] for v in self._subs(k).values()), default=1)

    def rule(self, k: int, j: int = 0) -> _Rule:
        """The integration rule of each env's part j of step k (implicit midpoint unless the scene's rule is backward
        Euler or the (sub)step fell back to it; the identity for an env whose sub-steps are over)."""
        B = self.dof.shape[1]
        dt = self.sim.model.dt
        mp = bool(self.sim.kernel_params[0]["midpoint"])
        fell = self.fallback[k].copy() if self.fallback is not None else np.zeros(B, bool)
        subs = self._subs(k)
        h = np.full(B, dt)
        done = np.full(B, j >= 1)
        for e, (ns, *_, fl) in subs.items():
            h[e] = dt / ns
            done[e] = j >= ns
            fell[e] = bool(fl[min(j, ns - 1)])
        return _Rule.of(h, np.full(B, mp) & ~fell, done)

    def _part(self, k: int, j: int = 0) -> _Part:
        """Part j of step k (:class:`_Part`): the whole step where no env took sub-steps."""
        d1, t0, b0 = self._frames(k)
        x0, pre, u0, x1, t1 = self._start(k), self.dof[k], self.vel[k], self.dof[k + 1], self.tangent[k + 1]
        subs = self._subs(k)
        if subs or j > 0:
            x0, pre, u0, d1, t0, b0, x1, t1 = (np.array(a, copy=True) for a in (x0, pre, u0, d1, t0, b0, x1, t1))
            end = (self.dof[k + 1], self.vel[k + 1], self.ref_d1[k + 1], self.tangent[k + 1], self.ref_twist[k + 1])
            for e in range(x0.shape[0]):
                if e in subs:
                    ns, xs, vs, d1s, ts, bs, _ = subs[e]
                    a, b = (j, j + 1) if j < ns else (ns, ns)
                    x0[e], u0[e], d1[e], t0[e], b0[e] = xs[a], vs[a], d1s[a], ts[a], bs[a]
                    x1[e], t1[e] = xs[b], ts[b]
                    if j > 0:
                        pre[e] = xs[a]
                elif j > 0:  # its one step is over: the part leaves it at the step's end
                    x0[e], u0[e], d1[e], t0[e], b0[e] = (v[e] for v in end)
                    pre[e], x1[e], t1[e] = end[0][e], end[0][e], end[3][e]
        return _Part(k, j, x0, pre, u0, d1, t0, b0, x1, t1, self.rule(k, j))

    def _linearise(self, part: _Part, names: tuple[str, ...]) -> _Lin:
        sim, m = self.sim, self.sim.model
        k = part.k
        rule = part.rule
        h = rule.h_solve  # (B,) the step of the residual solved (half the step for the midpoint rule)
        hc = h[:, None]
        planar = m.mode == "2d"
        kl = KL_2D if planar else KL_3D
        B, n = self.dof.shape[1], self.dof.shape[2]
        N = self.ref_twist.shape[2]
        E = N - 1
        want_kb, want_tb = "kappa_bar" in names, "tau_bar" in names
        want_sc = any(nm in _SCALARS[:3] for nm in names)
        ab = np.zeros((B, n + kl, 2 * kl + 1))
        rows = ELEMENT_ROWS[planar]
        kbc = np.zeros((B, N, rows, 2) if want_kb else (1, 1, 1, 2))
        tbc = np.zeros((B, N, rows) if want_tb else (1, 1, 1))
        sc = np.zeros((B, n, 3) if want_sc else (1, 1, 3))
        prm = sim.kernel_params[0]
        # friction (slip velocity) and drag (velocity, and the tangent lagged at the start): ∂f/∂x is not diagonal
        want_start = (int(prm["n_obstacles"]) > 0 and bool(prm["friction_on"])) or bool(prm["drag_on"])
        st_band = np.zeros((B, n + kl, 2 * kl + 1) if want_start else (1, 1, 1))
        rod, rod_e, rod_g, rod_m = self._rods(k)
        c = np.ascontiguousarray
        start = StateArrays(dof=c(part.x0), vel=c(part.u0), ref_d1=c(part.d1), tangent=c(part.t0), ref_twist=c(part.b0),
                            time=np.zeros(B),
                            failed=np.zeros(B, np.bool_))
        y = part.solved()
        pairs = bool(prm["rod_pairs"])
        prm_band = sim.kernel_params.copy()
        prm_band[0]["rod_pairs"] = False  # the band without the edge pairs: they are a term of their own (_pair_terms)
        linearise_step(start, c(y), ControlArrays(c(self.kappa_bar[k]), c(self.tau_bar[k])), h,
                       RodFactors(rod, rod_e, rod_g, rod_m), prm_band, self._cd,
                       Wanted(want_kb, want_tb, want_sc, want_start, FRICTION_FD_STEP if want_start else 1e-6),
                       Linearisation(ab, kbc, tbc, sc, st_band))
        pos_dof = np.ones(n, bool) if planar else (np.arange(n) % 4 != 3)
        fixed = sim.kernel_rod.fixed.astype(bool)
        mass = sim.kernel_rod.mass
        G = None
        if not planar:  # ∂f/∂θ's columns before the constraints: the elastic part is ∂f/∂φ
            th = 4 * np.arange(E) + 3
            g = band_columns(ab, kl, th)[..., None]
            g[:, :, kl, 0] -= mass[:, th] / hc**2
            G = LocalColumns(g, 3 - kl, 4, n)
            G.zero_rows(fixed)
        held = np.flatnonzero(fixed)
        Jc = np.zeros((B, n, held.size))  # the constrained DOFs' columns: a change of a held DOF moves the others
        rows = held[:, None] - kl + np.arange(2 * kl + 1)[None, :]
        ok = (rows >= 0) & (rows < n)
        Jc[:, rows[ok], np.nonzero(ok)[0]] = band_columns(ab, kl, held)[:, ok]
        Jc[:, fixed, :] = 0.0
        _constrain(ab, fixed, kl)  # constrained DOFs: identity rows and columns (residual 0, they do not move)
        damp = sim.kernel_rod.damping  # (R, 1)
        Fx = -(mass / hc**2 + np.where(pos_dof, damp * mass, 0.0) / hc) * np.ones((B, 1))  # (B, n)
        Fu = -mass / hc * np.ones((B, 1))
        Fx[:, fixed], Fu[:, fixed] = 0.0, 0.0
        if want_start:  # the start positions' columns by differences, the twist angles' inertia on the diagonal
            S = _dense(st_band, n, kl)
            S[:, fixed, :] = 0.0
            S[:, np.arange(n), np.arange(n)] += np.where(pos_dof[None, :], 0.0, Fx)
            Fx = S
        low: dict = {}
        if pairs:
            low, Fx = self._pair_terms(part, y, Fx, Jc)
        P: dict = {}
        dpn = 2 if planar else 4  # node i's element starts at DOF dpn (i − 1)
        if want_kb:
            P["kappa_bar"] = LocalColumns(kbc, -dpn, dpn, n)
        if want_tb:
            P["tau_bar"] = LocalColumns(tbc[..., None], -dpn, dpn, n)
        for cols in P.values():
            cols.zero_rows(fixed)
        for j, nm in enumerate(_SCALARS[:3]):
            if want_sc and nm in names:
                P[nm] = sc[:, :, j:j + 1] * ~fixed[None, :, None]
        for nm in _CONTACT_FIELDS:
            if nm in names:  # after linearise_step: the contact data hold this step's candidates
                P[nm] = self._contact_column(part, nm, rod) * ~fixed[None, :, None]
        for nm in _POSE_FIELDS:
            if nm in names:
                P[nm] = self._pose_columns(part, nm, rod) * ~fixed[None, :, None]
        if "log_radius" in names:
            P["log_radius"] = self._radius_column(part, rod) * ~fixed[None, :, None]
        if "damping" in names:  # the damping force c m (y − x)/h on positions
            P["damping"] = ((mass * pos_dof * ~fixed) * (y - part.x0) / hc)[:, :, None]
        if planar:
            return _Lin(k, ab, kl, Fx, Fu, None, None, None, P, rule, low=low, Jc=Jc)
        link = sim.kernel_rod.link.astype(bool)
        # the transport runs from the step's start tangents (a turning clamp's turned first); a change of the state
        # before the step moves them as the positions before the motion (the motion is held: it moves no frame of a
        # free DOF)
        t0, t1 = part.t0, part.t1
        a = EdgeTurns.of_transport(t0, t1, part.pre, t0, link)
        b = EdgeTurns.of_transport(t0, t1, part.x1, t1, link)
        a.w[rule.identity], b.w[rule.identity] = 0.0, 0.0  # an env the part leaves: its frames stay
        if not rule.any_midpoint:
            return _Lin(k, ab, kl, Fx, Fu, G, a, b, P, rule, low=low, Jc=Jc)
        ty = _tangents(y, link, t1)  # the residual's frames are transported to y's tangents; the end's to x''s
        ay, by = EdgeTurns.of_transport(t0, ty, part.pre, t0, link), EdgeTurns.of_transport(t0, ty, y, ty, link)
        ay.w[rule.identity], by.w[rule.identity] = 0.0, 0.0
        return _Lin(k, ab, kl, Fx, Fu, G, ay, by, P, rule, a_end=a, b_end=b, low=low, Jc=Jc)

    def _pair_terms(self, part: _Part, y: np.ndarray, Fx: np.ndarray, Jc: np.ndarray) -> tuple[dict, np.ndarray]:
        """The part's edge-pair contact per env: its Jacobian as the term U E_Sᵀ of J (S the free position DOFs of
        the nodes of the pairs within reach, U (n, s) their columns, constrained rows 0), its columns at the
        constrained DOFs of those nodes added to ``Jc`` (B, n, held) (a change of them is carried, as the band's),
        and with friction its dependence on the start positions (the slip velocity) added to ``Fx`` (made dense).
        Central differences of the pairs' residual (:func:`sim.kernels.probe.pair_linearisation`), with friction
        at step 1e-7, extrapolated, as the start band."""
        sim = self.sim
        prm = sim.kernel_params
        friction = float(prm[0]["friction"]) > 0.0
        B, n = y.shape
        x0, h = part.x0, part.rule.h_solve
        fixed = sim.kernel_rod.fixed.astype(bool)
        held = np.flatnonzero(fixed)
        dofs = np.empty(n, np.int64)
        cols = np.empty((n, n))
        start_cols = np.empty((n, n) if friction else (1, 1))
        c = np.ascontiguousarray
        low = {}
        for e in range(B):
            s = pair_linearisation(prm, sim.kernel_rod, c(y[e]), c(x0[e]), float(h[e]), FRICTION_FD_STEP, True,
                                   friction, dofs, cols, start_cols)
            if s == 0:
                continue
            S = dofs[:s].copy()
            U = cols[:, :s].copy()
            U[fixed] = 0.0
            free = ~fixed[S]
            if not free.all():  # the constrained DOFs' columns: carried as the band's (_linearise: Jc)
                Jc[e][:, np.searchsorted(held, S[~free])] += U[:, ~free]
            if free.any():
                low[e] = (S[free], U[:, free])
            if friction:
                if Fx.ndim == 2:
                    dense = np.zeros((B, n, n))
                    dense[:, np.arange(n), np.arange(n)] = Fx
                    Fx = dense
                V = start_cols[:, :s].copy()
                V[fixed] = 0.0
                Fx[e][:, S] += V
        return low, Fx

    def _pair_residuals(self, part: _Part, prm_arr, rod=None) -> np.ndarray:
        """(B, n) the part's edge-pair residual of every env at its solution with the parameters record ``prm_arr``
        (and the rod record ``rod``: the simulator's by default)."""
        y, x0, h = part.solved(), part.x0, part.rule.h_solve
        out = np.empty(y.shape)
        c = np.ascontiguousarray
        for e in range(y.shape[0]):
            pair_residual(prm_arr, self.sim.kernel_rod if rod is None else rod, c(y[e]), c(x0[e]), float(h[e]), out[e])
        return out

    def _radius_column(self, part: _Part, rod) -> np.ndarray:
        """(B, n, 1) ∂f/∂(ln r) of the part: central differences of its residual with every edge's radius scaled
        by e^ε (the stretching stiffness and the position DOFs' masses and weights by e^2ε, the bending and
        twisting stiffness and the twist angles' inertia by e^4ε, the contact radius by e^ε)."""
        m = self.sim.model
        narrow = [r for r in m.spec.rods if getattr(r, "cross_section", "circle") != "circle"]
        if narrow:
            raise GradientError(f"log_radius: rod {narrow[0].name!r} has a {narrow[0].cross_section} section, not "
                                "a radius")
        n = self.dof.shape[2]
        pos_dof = np.ones(n, bool) if m.mode == "2d" else (np.arange(n) % 4 != 3)
        weight = self.sim.kernel_rod.grav  # the weights (R, n) (RodData: the record's external forces are gravity's)
        prm = self.sim.kernel_params
        obstacles, pairs = self.contact is not None, bool(prm[0]["rod_pairs"])
        cd = self.contact if obstacles else self._cd

        def scaled(eps: float) -> np.ndarray:
            s2 = np.exp(2.0 * eps)
            r = rod._replace(EA=rod.EA * s2, EI1=rod.EI1 * s2**2, EI2=rod.EI2 * s2**2, GJ=rod.GJ * s2**2,
                             mass=rod.mass * np.where(pos_dof, s2, s2**2), grav=rod.grav + (s2 - 1.0) * weight,
                             edge_radius=rod.edge_radius * np.exp(eps))
            res = self._residuals(part, r)(prm, cd)
            return res + self._pair_residuals(part, prm, r) if pairs else res

        return self._difference(scaled, 1e-6)[:, :, None]

    def _residuals(self, part: _Part, rod):
        """A function (prm, cd) -> (B, n): the part's residual of every env at its solution with the parameters record
        ``prm`` and the contact data ``cd`` (the candidates the part's linearisation listed)."""
        B, n = self.dof.shape[1], self.dof.shape[2]
        kl = KL_2D if self.sim.model.mode == "2d" else KL_3D
        f = np.zeros(n)
        ab = np.zeros((n + kl, 2 * kl + 1))
        c = np.ascontiguousarray
        k = part.k
        y, x0, h = part.solved(), part.x0, part.rule.h_solve
        args = [(c(y[e]), c(x0[e]), c(part.u0[e]), c(part.d1[e]), c(part.t0[e]), c(part.b0[e]), float(h[e]),
                 c(self.kappa_bar[k, e]), c(self.tau_bar[k, e]), rod) for e in range(B)]

        def residuals(prm, cd) -> np.ndarray:
            res = np.zeros((B, n))
            for e in range(B):
                assemble_at(e, *args[e], prm, cd, f, ab)
                res[e] = f
            return res

        return residuals

    def _difference(self, moved, step: float) -> np.ndarray:
        """Central difference (moved(ε) − moved(−ε))/(2ε) of a residual function ``moved``; with friction step 1e-7
        (``step`` scaled by FRICTION_FD_STEP/1e-6) extrapolated from ε and ε/2, as the start band."""
        prm = self.sim.kernel_params[0]
        if not (bool(prm["friction_on"]) or (bool(prm["rod_pairs"]) and float(prm["friction"]) > 0.0)):
            return (moved(step) - moved(-step)) / (2.0 * step)
        step *= FRICTION_FD_STEP / 1e-6
        d1, d2 = ((moved(eps) - moved(-eps)) / (2.0 * eps) for eps in (step, 0.5 * step))
        return (4.0 * d2 - d1) / 3.0

    def _contact_column(self, part: _Part, name: str, rod) -> np.ndarray:
        """(B, n, 1) ∂f/∂p of the part for the contact stiffness's log factor, the [contact] μ or the contact distance's
        log factor, at the solution, evaluated with the candidates the step's linearisation listed in the contact
        data. The residual is linear in the stiffness and in μ, so their columns are f(2k) − f(k) and f(μ + 1) − f(μ)
        (friction acting, also from μ = 0); δ enters the energy's shape: central differences in ln δ."""
        B, n = self.dof.shape[1], self.dof.shape[2]
        out = np.zeros((B, n, 1))
        prm0 = self.sim.kernel_params
        obstacles, pairs = self.contact is not None, bool(prm0[0]["rod_pairs"])
        if not (obstacles or pairs):
            return out
        residuals = self._residuals(part, rod) if obstacles else None

        def at(**changed) -> np.ndarray:
            prm = prm0.copy()
            for key, v in changed.items():
                prm[0][key] = v
            res = residuals(prm, self.contact) if obstacles else np.zeros((B, n))
            return res + self._pair_residuals(part, prm) if pairs else res

        if name == "log_contact_stiffness":
            out[:, :, 0] = at(contact_k=2.0 * float(prm0[0]["contact_k"])) - at()
        elif name == "friction":
            out[:, :, 0] = at(friction=float(prm0[0]["friction"]) + 1.0, friction_on=True) - at()
        else:
            delta = float(prm0[0]["contact_delta"])
            out[:, :, 0] = self._difference(lambda eps: at(contact_delta=delta * np.exp(eps)), 1e-6)
        return out

    def _pose_columns(self, part: _Part, name: str, rod) -> np.ndarray:
        """(B, n, 3 M) ∂f/∂p of the part for every obstacle's position or turn (column 3 j + axis): central differences
        of the residual at the solution with the pose moved and its world arrays derived anew, with the candidates
        the step's linearisation listed."""
        B, n = self.dof.shape[1], self.dof.shape[2]
        M = self.sim.model.obstacles.count
        out = np.zeros((B, n, 3 * M))
        if self.contact is None or M == 0:
            return out
        step = 1e-6
        if name == "obstacle_position":
            step *= max(1.0, float(np.abs(self.poses["obstacle_position"]).max()))
        residuals = self._residuals(part, rod)
        prm = self.sim.kernel_params
        for j in range(M):
            for axis in range(3):
                out[:, :, 3 * j + axis] = self._difference(
                    lambda eps, j=j, axis=axis: residuals(prm, self._moved_contact(name, j, axis, eps)), step)
        return out

    def _moved_contact(self, name: str, j: int, axis: int, d: float):
        """The tape's contact data with obstacle j moved by d along ``axis`` or turned by d about it (world axes,
        about its local origin) in every env."""
        g = self.sim.model.obstacles
        poses = {nm: v.copy() for nm, v in self.poses.items()}
        if name == "obstacle_position":
            poses["obstacle_position"][:, j, axis] += d
        else:
            turn = np.zeros(4)
            turn[0], turn[1 + axis] = np.cos(0.5 * d), np.sin(0.5 * d)
            poses["obstacle_orientation"][:, j] = _quat_mul(turn, poses["obstacle_orientation"][:, j])
        B, M = poses["obstacle_position"].shape[:2]
        p0, p1, rot, box = np.zeros((B, M, 3)), np.zeros((B, M, 3)), np.zeros((B, M, 3, 3)), np.zeros((B, M, 2, 3))
        world_arrays(g, poses["obstacle_position"], poses["obstacle_orientation"], poses["obstacle_a"],
                     poses["obstacle_b"], poses["obstacle_radius"], p0, p1, rot, box)
        return self.contact._replace(p0=p0, p1=p1, rot=rot, box=box)

    def _gravity_columns(self, B: int) -> np.ndarray:
        """(B, n, 3) ∂f/∂g of every env (the same for every step)."""
        rod = self.sim.kernel_rod
        n = self.dof.shape[2]
        out = np.zeros((B, n, 3))
        mass = np.broadcast_to(rod.mass, (B, n))
        if self.sim.model.mode == "2d":
            out[:, 0::2, 0] = -mass[:, 0::2]
            out[:, 1::2, 2] = -mass[:, 1::2]
        else:
            for c in range(3):
                out[:, c::4, c] = -mass[:, c::4]
        out[:, rod.fixed.astype(bool)] = 0.0
        return out

    def _force_dofs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(nodes, components, DOFs) of the point forces' entries that act: each free node's x, y, z (2-D: x, z)."""
        N = self.tau_bar.shape[2]
        planar = self.sim.model.mode == "2d"
        comps = np.array([0, 2] if planar else [0, 1, 2])
        nodes = np.repeat(np.arange(N), comps.size)
        comp = np.tile(comps, N)
        dofs = 2 * nodes + comp // 2 if planar else 4 * nodes + comp
        free = ~self.sim.kernel_rod.fixed.astype(bool)[dofs]
        return nodes[free], comp[free], dofs[free]

    def _rhs_params(self, lin: _Lin, name: str, tan: np.ndarray, k: int) -> np.ndarray:
        """(B, n) ∂f/∂p · δp of step k for the tangent ``tan`` of parameter ``name``."""
        if name == "gravity":
            return np.einsum("bnc,bc->bn", self._gravity_columns(tan.shape[0]), tan)
        if name == "force":
            nodes, comps, dofs = self._force_dofs()
            out = np.zeros((tan.shape[1], self.dof.shape[2]))
            out[:, dofs] = -tan[k][:, nodes, comps]
            return out
        if name in _POSE_FIELDS:
            v = tan.reshape(tan.shape[0], -1)
        elif name == "kappa_bar":
            v = tan[k].reshape(tan.shape[1], -1)
        elif name == "tau_bar":
            v = tan[k]
        else:
            v = tan[:, None]
        return _columns_times(lin.P[name], v)

    # ------------------------------------------------------------------ material frames (3-D)
    def material_frame(self, k: int, edge: int = -1) -> np.ndarray:
        """(B, 3, 3) the material frame of edge ``edge`` in state k (after k steps), columns (m1, m2, t)
        (docs/physics.md §1.3)."""
        e = self._edge(edge)
        t, d1 = np.asarray(self.tangent[k])[:, e], np.asarray(self.ref_d1[k])[:, e]
        th = np.asarray(self.dof[k])[:, 4 * e + 3]
        d2 = np.cross(t, d1)
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        return np.stack([c * d1 + s * d2, c * d2 - s * d1, t], axis=2)

    def frame_cotangents(self, k: int, edge: int, dL_dR: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cotangents ("dof" (B, n), "phi" (B, E)) of state k for an objective L whose derivative with respect to
        the :meth:`material_frame` R of ``edge`` is ``dL_dR`` (B, 3, 3). The frame turns as δR = [ω]× R with
        ω = (δθ + δφ) t + t × δt, δt = (I − t tᵀ) δe/|e| (the director parallel-transported with its tangent, turned by
        φ beyond it), so with g = Σ_j R_j × (dL/dR)_j: ∂L/∂θ = ∂L/∂φ = g·t and ∂L/∂x_b = −∂L/∂x_a = (g × t)/|e|."""
        e = self._edge(edge)
        R = self.material_frame(k, e)
        G = np.asarray(dL_dR, dtype=np.float64)
        B, n = self.dof.shape[1], self.dof.shape[2]
        if G.shape != (B, 3, 3) or not np.all(np.isfinite(G)):
            raise GradientError(f"dL_dR: expected finite ({B}, 3, 3), got shape {G.shape}")
        g = np.cross(R, G, axis=1).sum(axis=2)  # Σ_j R[:, :, j] × G[:, :, j]
        t = R[:, :, 2]
        x = np.asarray(self.dof[k])
        length = np.linalg.norm(x[:, 4 * e + 4:4 * e + 7] - x[:, 4 * e:4 * e + 3], axis=1)
        dof, phi = np.zeros((B, n)), np.zeros((B, self.ref_d1.shape[2]))
        turn = np.einsum("bi,bi->b", g, t)
        dof[:, 4 * e + 3] = turn
        phi[:, e] = turn
        u = np.cross(g, t) / length[:, None]
        dof[:, 4 * e + 4:4 * e + 7] = u
        dof[:, 4 * e:4 * e + 3] = -u
        return dof, phi

    def _edge(self, edge: int) -> int:
        if self.sim.model.mode == "2d":
            raise GradientError("material frames: a planar rod has none")
        E = self.ref_d1.shape[2]
        if not -E <= edge < E:
            raise GradientError(f"edge {edge} is not an edge of the rod (0 … {E - 1})")
        return edge % E

    # ------------------------------------------------------------------ forward mode
    def jvp(self, tangents: dict | list[dict]) -> dict:
        """Tangents of every state of the rollout for the parameter tangents ``tangents`` (name -> array shaped as
        in the module docstring; absent = 0). Returns {"dof": (T + 1, B, n), "vel": (T + 1, B, n)}; for a list of
        Q tangent dicts, arrays (Q, T + 1, B, n) (one linearisation and factorisation per step serves them all)."""
        many = isinstance(tangents, (list, tuple))
        tans = [_checked(t, self) for t in (tangents if many else [tangents])]
        T, B, n = self.steps, self.dof.shape[1], self.dof.shape[2]
        Q = len(tans)
        planar = self.sim.model.mode == "2d"
        fixed = self.sim.kernel_rod.fixed.astype(bool)
        E = self.ref_d1.shape[2]
        held = np.flatnonzero(fixed)
        moves_held = any("dof0" in t and np.any(t["dof0"][:, held] != 0.0) for t in tans)
        if moves_held:
            self._check_held()
        ddof = np.zeros((Q, T + 1, B, n))
        dvel = np.zeros((Q, T + 1, B, n))
        names = tuple(sorted({nm for t in tans for nm in t if nm not in ("dof0", "vel0")}))
        zero = np.zeros((B, n))
        dx = np.stack([t.get("dof0", zero) for t in tans], axis=2)  # (B, n, Q)
        du = np.stack([t.get("vel0", zero) for t in tans], axis=2)
        phi = np.zeros((B, E, Q))
        ddof[:, 0], dvel[:, 0] = dx.transpose(2, 0, 1), du.transpose(2, 0, 1)
        for k in range(T):
            for j in range(self.parts(k)):  # a step the retry ladder split: sub-step by sub-step
                lin = self._linear(k, names, j)
                rhs = lin.start_term(dx) + lin.Fu[:, :, None] * du
                if not planar:
                    rhs += lin.G.apply(phi + lin.a.apply(dx))
                for q, t in enumerate(tans):
                    for nm in names:
                        if nm in t:
                            rhs[:, :, q] += self._rhs_params(lin, nm, t[nm], k)
                if moves_held:  # the constrained DOFs keep their change (dy = dx there) and move the others
                    rhs += lin.Jc @ dx[:, held]
                    rhs[:, held] = -dx[:, held]
                dy = -lin.solve(rhs)  # the solved-for point (the end; the midpoint rule: the half-step point)
                r = lin.rule
                dx1 = r.alpha[:, None, None] * dy + r.beta[:, None, None] * dx
                du = r.gamma[:, None, None] * (dy - dx) - r.delta[:, None, None] * du
                du[np.ix_(r.delta > 0.0, fixed)] = 0.0  # the midpoint rule sets the constrained DOFs' velocities to 0
                if not planar:
                    a_end, b_end = lin.end_maps()
                    phi = phi + a_end.apply(dx) + b_end.apply(dx1)
                dx = dx1
            ddof[:, k + 1], dvel[:, k + 1] = dx.transpose(2, 0, 1), du.transpose(2, 0, 1)
        if many:
            return {"dof": ddof, "vel": dvel}
        return {"dof": ddof[0], "vel": dvel[0]}

    # ------------------------------------------------------------------ reverse mode
    def vjp(self, cotangents: dict, params=PARAMETERS) -> dict:
        """Gradients of the scalar Σ ⟨cotangent, state⟩ with respect to ``params``; ``cotangents``: "dof" and/or
        "vel", each (T + 1, B, n) (every state of the rollout) or (B, n) (the final state), and in 3-D "phi",
        (T + 1, B, E) or (B, E): the turn of each edge's reference director about its tangent (an objective on a
        material frame: :meth:`frame_cotangents`). One backward pass: transposed solves with the steps' Jacobians."""
        T, B, n = self.steps, self.dof.shape[1], self.dof.shape[2]
        cx = _cotangent(cotangents.get("dof"), T, B, n)
        cu = _cotangent(cotangents.get("vel"), T, B, n)
        unknown = set(cotangents) - {"dof", "vel", "phi"}
        if unknown:
            raise GradientError(f"unknown cotangent {sorted(unknown)[0]!r}; known: dof, vel, phi")
        if "phi" in cotangents and self.sim.model.mode == "2d":
            raise GradientError("cotangent 'phi': a planar rod has no reference directors to turn")
        E = self.ref_d1.shape[2]
        cphi = _cotangent(cotangents.get("phi"), T, B, E)
        for nm in params:
            if nm not in PARAMETERS:
                raise GradientError(f"unknown parameter {nm!r}; known: {', '.join(PARAMETERS)}")
        planar = self.sim.model.mode == "2d"
        fixed = self.sim.kernel_rod.fixed.astype(bool)
        N = self.tau_bar.shape[2]
        M = self.sim.model.obstacles.count
        out = {nm: np.zeros(_param_shape(nm, T, B, n, N, M)) for nm in params}
        kept = self._held_ok()  # a turned clamp does not keep a change (jvp refuses one): its DOFs' gradient is 0
        held = np.flatnonzero(fixed) if kept else np.zeros(0, np.int64)
        names = tuple(nm for nm in params if nm not in ("dof0", "vel0"))
        gx = cx[T].copy()  # (B, n) adjoint of x_k (total, including the later steps' dependence)
        gu = cu[T].copy()
        gphi = cphi[T].copy()  # (B, E) adjoint of φ_k
        for k in range(T - 1, -1, -1):
            for j in range(self.parts(k) - 1, -1, -1):  # a step the retry ladder split: sub-step by sub-step
                lin = self._linear(k, names, j)
                # the solved-for point y gives x_{k+1} = α y + β x_k, u_{k+1} = γ (y − x_k) − δ u_k and
                # φ_{k+1} = φ_k + a_end x_k + b_end x_{k+1}
                r = lin.rule
                gu = gu.copy()
                gu[np.ix_(r.delta > 0.0, fixed)] = 0.0  # the midpoint rule sets constrained DOFs' velocities to 0
                gx_end = gx
                if not planar:
                    a_end, b_end = lin.end_maps()
                    gx_end = gx + b_end.adjoint(gphi)
                al, be, ga, de = (v[:, None] for v in (r.alpha, r.beta, r.gamma, r.delta))
                gy = al * gx_end + ga * gu
                gx_prev = be * gx_end - ga * gu + (cx[k] if j == 0 else 0.0)
                gu_prev = -de * gu + (cu[k] if j == 0 else 0.0)
                if not planar:
                    gx_prev = gx_prev + a_end.adjoint(gphi)
                lam = lin.solve(gy[:, :, None], transpose=True)[:, :, 0]  # y = −J⁻¹ rhs ⇒ ∂/∂rhs = −λ
                for nm in names:
                    if nm == "gravity":
                        out[nm] += -np.einsum("bn,bnc->bc", lam, self._gravity_columns(B))
                        continue
                    if nm == "force":
                        nodes, comps, dofs = self._force_dofs()
                        out[nm][k][:, nodes, comps] += lam[:, dofs]
                        continue
                    g = -_columns_adjoint(lin.P[nm], lam)
                    if nm in _POSE_FIELDS:
                        out[nm] += g.reshape(out[nm].shape)
                    elif nm == "kappa_bar":
                        out[nm][k] += g.reshape(B, N, 2)
                    elif nm == "tau_bar":
                        out[nm][k] += g
                    else:
                        out[nm] += g[:, 0]
                gx_prev = gx_prev - lin.start_adjoint(lam)
                if held.size:  # the constrained DOFs keep their change: λ there, less what they move elsewhere
                    gx_prev[:, held] += lam[:, held] - np.einsum("bnc,bn->bc", lin.Jc, lam)
                gu_prev = gu_prev - lin.Fu * lam
                if not planar:
                    Gl = -lin.G.adjoint(lam)
                    gx_prev = gx_prev + lin.a.adjoint(Gl)
                    gphi = gphi + Gl
                gx, gu = gx_prev, gu_prev
            gphi = gphi + cphi[k]
        if "dof0" in out:
            out["dof0"][:] = gx
            if not kept:
                out["dof0"][:, fixed] = 0.0
        if "vel0" in out:
            out["vel0"][:] = gu
        return out


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a ∘ b of quaternions wxyz (a (4,), b (..., 4))."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def _constrain(ab: np.ndarray, fixed: np.ndarray, kl: int) -> None:
    """Make the constrained DOFs' rows and columns of the padded bands ``ab`` (B, n + kl, 2 kl + 1) identity."""
    n = ab.shape[1] - kl
    d = np.arange(2 * kl + 1)
    for k in np.flatnonzero(fixed):
        ab[:, k, :] = 0.0
        r = k + kl - d  # the rows whose band entry d lies in column k
        ok = (r >= 0) & (r < n)
        ab[:, r[ok], d[ok]] = 0.0
        ab[:, k, kl] = 1.0


def _tangents(x: np.ndarray, link: np.ndarray, held: np.ndarray) -> np.ndarray:
    """(B, E, 3) unit edge tangents of the 3-D DOFs x (B, n); a joint edge keeps ``held``'s (it keeps its frame)."""
    B, E = held.shape[0], held.shape[1]
    pos = x.reshape(B, E + 1, 4)[:, :, :3]
    e = pos[:, 1:] - pos[:, :-1]
    t = e / np.linalg.norm(e, axis=2, keepdims=True).clip(1e-300)
    t[:, ~link] = held[:, ~link]
    return t


def _columns_times(P, v: np.ndarray) -> np.ndarray:
    """∂f/∂p · v for every env: P dense (B, n, k) or :class:`LocalColumns`, v (B, k)."""
    return P.apply(v) if isinstance(P, LocalColumns) else np.einsum("bnk,bk->bn", P, v)


def _columns_adjoint(P, lam: np.ndarray) -> np.ndarray:
    """(∂f/∂p)ᵀ λ for every env: λ (B, n) → (B, k)."""
    return P.adjoint(lam) if isinstance(P, LocalColumns) else np.einsum("bnk,bn->bk", P, lam)


def _param_shape(name, T, B, n, N, M=0):
    if name in _POSE_FIELDS:
        return (B, M, 3)
    return {"dof0": (B, n), "vel0": (B, n), "kappa_bar": (T, B, N, 2), "tau_bar": (T, B, N), "force": (T, B, N, 3),
            "log_youngs_modulus": (B,), "log_shear_modulus": (B,), "log_density": (B,), "log_radius": (B,),
            "damping": (B,),
            "gravity": (B, 3), "log_contact_stiffness": (B,), "friction": (B,), "log_contact_delta": (B,)}[name]


def _checked(tangents: dict, tape: Tape) -> dict:
    T, B, n = tape.steps, tape.dof.shape[1], tape.dof.shape[2]
    N = tape.tau_bar.shape[2]
    out = {}
    for nm, v in tangents.items():
        if nm not in PARAMETERS:
            raise GradientError(f"unknown parameter {nm!r}; known: {', '.join(PARAMETERS)}")
        arr = np.asarray(v, dtype=np.float64)
        want = _param_shape(nm, T, B, n, N, tape.sim.model.obstacles.count)
        if arr.shape != want:
            raise GradientError(f"tangent of {nm!r} has shape {arr.shape}, expected {want}")
        if not np.all(np.isfinite(arr)):
            raise GradientError(f"tangent of {nm!r} has non-finite values")
        out[nm] = arr
    return out


def _cotangent(v, T, B, n) -> np.ndarray:
    out = np.zeros((T + 1, B, n))
    if v is None:
        return out
    arr = np.asarray(v, dtype=np.float64)
    if arr.shape == (B, n):
        out[T] = arr
    elif arr.shape == (T + 1, B, n):
        out[:] = arr
    else:
        raise GradientError(f"cotangent has shape {arr.shape}, expected {(B, n)} or {(T + 1, B, n)}")
    if not np.all(np.isfinite(out)):
        raise GradientError("cotangent has non-finite values")
    return out


def rollout(sim, state, controls, *, checkpoint: int | None = None) -> Tape:
    """Run ``sim`` from ``state`` (advanced in place) for T steps under ``controls`` (a sequence of T
    :class:`sim.Control`, one per step) and record what :class:`Tape` needs to differentiate it. Raises
    :class:`GradientError` for what the derivatives do not cover (a step that failed; contact between edges with a
    contact margin below δ).

    ``checkpoint=K``: keep the whole state only every K steps (and the controls) instead of every state; a pass that
    needs the states between two checkpoints steps ``sim`` again from the earlier one (each segment once per pass:
    the forward steps once more, for memory ∝ T/K + K states instead of T). The steps are deterministic, so the
    derivatives are those of the full tape to the last bit. A checkpointed tape keeps no linearisation between
    passes (:attr:`Tape.nbytes` is what it keeps)."""
    prm = sim.kernel_params[0]
    if bool(prm["rod_pairs"]) and float(prm["contact_margin"]) < float(prm["contact_delta"]):
        raise GradientError(f"derivatives through contact between edges need the [contact] margin "
                            f"({float(prm['contact_margin']):g} m) at least the distance delta "
                            f"({float(prm['contact_delta']):g} m), so that every pair in reach is found again")
    if sim._frame_loads is not None:
        raise GradientError("derivatives with moments or material-frame loads ([[load]] moment / frame = "
                            "\"material\", which depend on the configuration) are not available yet")
    controls = list(controls)
    if not controls:
        raise GradientError("rollout needs at least one control (one per step)")
    if checkpoint is not None and not (isinstance(checkpoint, (int, np.integer)) and checkpoint >= 1):
        raise GradientError(f"checkpoint must be a whole number of steps ≥ 1, got {checkpoint!r}")
    B = sim.envs
    contact = _contact_snapshot(sim, state) if int(prm["n_obstacles"]) > 0 else None
    poses = {nm: np.array(getattr(state, nm), copy=True) for nm in ObstacleWorld._POSE} if contact else None
    kbs = np.stack([np.array(c.kappa_bar, dtype=np.float64) for c in controls])
    tbs = np.stack([np.array(c.tau_bar, dtype=np.float64) for c in controls])
    common = dict(sim=sim, kappa_bar=kbs, tau_bar=tbs, poses=poses, contact=contact)
    m = sim.model
    cd = contact if contact is not None else spec_contact_data(m.obstacles, 1, m.node_count, m.edge_radius,
                                                               candidates=0)
    if checkpoint is not None:
        forces = [None if getattr(c, "force", None) is None else np.array(c.force, dtype=np.float64)
                  for c in controls]
        kept, unconverged, split = [], 0, False
        for k in range(len(controls)):
            if k % checkpoint == 0:
                kept.append(state.copy())
            rec = _advance(sim, state, _control(kbs, tbs, forces, k), k, cd)
            unconverged += rec[3]
            split = split or bool(rec[4])
        replay = _Replay(sim, int(checkpoint), kept, kbs, tbs, forces, cd)
        return replay.tape(common, unconverged, split)
    frames = [_snap(state, B)]
    steps = []
    for k, ctrl in enumerate(controls):
        steps.append(_advance(sim, state, ctrl, k, cd, frames[-1]))
        frames.append(_snap(state, B))
    dof, vel, d1, t, beta = (np.stack(a) for a in zip(*frames))
    gravs, moved, fallbacks, unconverged, subs = zip(*steps)
    return Tape(dof=dof, vel=vel, ref_d1=d1, tangent=t, ref_twist=beta, grav=np.stack(gravs),
                unconverged=int(sum(unconverged)),
                moved=dict(zip(_MOVED, (np.stack(a) for a in zip(*moved)))) if sim._motion else None,
                fallback=np.stack(fallbacks), subs=list(subs) if any(subs) else None, **common)


_STATE_FIELDS = ("dof", "vel", "ref_d1", "tangent", "ref_twist")  # a tape's records of every state (T + 1, …)
_MOVED = ("dof", "ref_d1", "tangent", "ref_twist")  # the start of each step with its prescribed motion applied


def _snap(state, B: int) -> tuple:
    """The state's records (:data:`_STATE_FIELDS`), copied."""
    return (state.dof.reshape(B, -1).copy(), state.dof_vel.reshape(B, -1).copy(), state.edge_ref_d1.copy(),
            state.edge_tangent.copy(), state.node_ref_twist.copy())


def _control(kbs, tbs, forces, k: int) -> Control:
    return Control(kbs[k], tbs[k], forces[k])


def _advance(sim, state, ctrl, k: int, cd, before: tuple | None = None) -> tuple:
    """Take step ``k`` of a rollout (``state`` in place) and return what a tape records of it: its external forces
    (B, n) (gravity, loads and the control's node forces: known inputs held over the step), the state its kernel
    started from with the step's prescribed motion applied (a tuple of :data:`_MOVED`; None without motion), which
    envs' midpoint steps were redone by backward Euler (B,), how many envs ended unconverged, and the sub-steps of
    the envs the retry ladder split ({env: …}, :func:`_substeps`; ``cd`` the contact data they are taken with;
    ``before``: the caller's :func:`_snap` of the state before the step, taken here if None)."""
    B = sim.envs
    force = getattr(ctrl, "force", None)
    grav = (sim._external_forces(state.time, force) if sim._loads or force is not None else
            np.broadcast_to(sim.kernel_rod.grav, (B, sim.kernel_rod.grav.shape[1])).copy())
    moved = None
    if before is None:
        before = _snap(state, B)
    if sim._motion:  # what the step's own motion stage will do, on a copy: moved DOFs, turned clamp frames
        pre = state.copy()
        sim._prescribe(pre)
        moved = (pre.dof.reshape(B, -1).copy(), pre.edge_ref_d1.copy(), pre.edge_tangent.copy(),
                 pre.node_ref_twist.copy())
    # the state the kernel starts from (for a split step's sub-steps): the motion moves DOFs and frames, not velocities
    start = before if moved is None else (moved[0], before[1], *moved[1:])
    st = sim.step(state, ctrl)
    bad = np.flatnonzero(st.failed)
    if bad.size:
        raise GradientError(f"step {k}: env {int(bad[0])} failed; a failed step has no derivative")
    subs = {int(e): _substeps(sim, int(e), int(st.substeps[e]), start, ctrl, grav, cd, state, k)
            for e in np.flatnonzero(st.substeps > 1)}
    return grav, moved, st.midpoint_fallbacks > 0, int(np.count_nonzero(~st.converged)), subs


def _substeps(sim, e: int, ns: int, start: tuple, ctrl, grav: np.ndarray, cd, state, k: int) -> tuple:
    """The ``ns`` sub-steps the retry ladder took env ``e``'s step ``k`` in, taken again from the kernel's start
    ``start`` with the ladder's own sub-step (:func:`sim.kernels.probe.substeps_at`): (ns, xs, vs, d1s, ts, bs, fell),
    the states before each sub-step and after the last (ns + 1, …) and the midpoint sub-steps redone by backward Euler
    (ns,). Raises :class:`GradientError` if they do not end where the step did."""
    x, v, d1, t, beta = (np.ascontiguousarray(a[e]) for a in start)
    n, E, N = x.size, d1.shape[0], beta.size
    xs, vs = np.empty((ns + 1, n)), np.empty((ns + 1, n))
    d1s, ts, bs = np.empty((ns + 1, E, 3)), np.empty((ns + 1, E, 3)), np.empty((ns + 1, N))
    fell = np.zeros(ns, np.int64)
    rod = sim.kernel_rod._replace(grav=np.ascontiguousarray(grav))
    done = substeps_at(e, x, v, d1, t, beta, np.ascontiguousarray(ctrl.kappa_bar[e], dtype=np.float64),
                       np.ascontiguousarray(ctrl.tau_bar[e], dtype=np.float64), ns, rod, sim.kernel_params, cd,
                       xs, vs, d1s, ts, bs, fell)
    end = state.dof.reshape(sim.envs, -1)[e]
    if done < ns or not np.allclose(xs[ns], end, rtol=0.0, atol=1e-9 * max(1.0, float(np.abs(end).max()))):
        raise GradientError(f"step {k}: env {e}'s {ns} sub-steps of the retry ladder were not taken again as the "
                            "step took them; its derivative is not available")
    return ns, xs, vs, d1s, ts, bs, fell.astype(bool)


class _Replay:
    """The records of a checkpointed rollout: the whole state every ``every`` steps and the controls; the records
    between two checkpoints are made again by stepping the simulator from the earlier one, one segment (``every``
    steps and the ``every`` + 1 states around them) at a time, the last one kept."""

    def __init__(self, sim, every: int, kept: list, kbs, tbs, forces, cd):
        self.sim, self.every, self.kept = sim, every, kept
        self.kbs, self.tbs, self.forces, self.cd = kbs, tbs, forces, cd
        self.T = kbs.shape[0]
        self._segment: tuple = (-1, None, None)
        self.replays = 0  # segments stepped again (each pass over the steps: ⌈T / every⌉)

    def _records(self, c: int) -> tuple:
        if self._segment[0] != c:
            self._segment = (-1, None, None)  # drop the old segment first: at most one is held
            B = self.sim.envs
            state = self.kept[c // self.every].copy()
            states, steps = [_snap(state, B)], []
            for k in range(c, min(c + self.every, self.T)):
                steps.append(_advance(self.sim, state, _control(self.kbs, self.tbs, self.forces, k), k, self.cd,
                                      states[-1]))
                states.append(_snap(state, B))
            self._segment = (c, states, steps)
            self.replays += 1
        return self._segment[1], self._segment[2]

    def state(self, field: int, k: int) -> np.ndarray:
        c = self._segment[0]
        if not (c >= 0 and c <= k <= c + len(self._segment[2])):
            c = min(k, self.T - 1) // self.every * self.every
        return self._records(c)[0][k - c][field]

    def step(self, field: int, k: int, part: int | None = None) -> np.ndarray:
        c = k // self.every * self.every
        rec = self._records(c)[1][k - c][field]
        return rec if part is None else rec[part]

    def tape(self, common: dict, unconverged: int, split: bool) -> "Tape":
        T, (B, n) = self.T, self.kept[0].dof.reshape(self.sim.envs, -1).shape
        snap = _snap(self.kept[0], B)
        lazy = {nm: _Lazy(lambda k, i=i: self.state(i, k), (T + 1,) + snap[i].shape)
                for i, nm in enumerate(_STATE_FIELDS)}
        moved = None
        if self.sim._motion:
            moved = {nm: _Lazy(lambda k, i=i: self.step(1, k, i), (T,) + snap[j].shape)
                     for i, (nm, j) in enumerate(zip(_MOVED, (0, 2, 3, 4)))}
        return Tape(**lazy, grav=_Lazy(lambda k: self.step(0, k), (T, B, n)), unconverged=unconverged, moved=moved,
                    fallback=_Lazy(lambda k: self.step(2, k), (T, B)),
                    subs=_Lazy(lambda k: self.step(4, k), (T,)) if split else None, _replay=self, **common)

    @property
    def nbytes(self) -> int:
        held = sum(getattr(s, nm).nbytes for s in self.kept for nm in STATE_ARRAYS)
        return held + sum(f.nbytes for f in self.forces if f is not None)


class _Lazy:
    """A tape's per-step records read like a (T [+ 1], …) array: ``a[k]``, ``a[k, e]``, ``a.shape``; any other
    index (a slice: ``tape.dof[:, 0]``) makes every record once, in order, and indexes their stack."""

    def __init__(self, get, shape: tuple):
        self._get, self.shape = get, shape

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, idx):
        k, rest = (idx[0], idx[1:]) if isinstance(idx, tuple) else (idx, ())
        if isinstance(k, (int, np.integer)):
            k = int(k) + (self.shape[0] if k < 0 else 0)
            if not 0 <= k < self.shape[0]:
                raise IndexError(f"record {k} of {self.shape[0]}")
            a = self._get(k)
            return a[rest] if rest else a
        return np.asarray(self)[idx]

    def __array__(self, dtype=None, copy=None):
        a = np.stack([self._get(k) for k in range(self.shape[0])])
        return a if dtype is None else a.astype(dtype)


def _contact_snapshot(sim, state):
    """The contact data of ``state``'s obstacles (poses, radii, active flags as they are now: a step does not move
    them) with a world and work space of its own, so that later steps of ``sim`` do not change it."""
    m = sim.model
    B = sim.envs
    world = ObstacleWorld(m.obstacles, B).update(state)
    held = dataclasses.make_dataclass("_Held", ["obstacle_radius", "obstacle_active"])(
        np.array(state.obstacle_radius, copy=True), np.array(state.obstacle_active, copy=True))
    return contact_data(m.obstacles, world, held, contact_scratch(B, m.node_count, m.obstacles.count, m.edge_radius))
