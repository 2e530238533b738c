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
* J: exact in 2-D. In 3-D the Newton Jacobian leaves out how the transported frames turn with the new positions;
  its θ columns are kept and its position columns replaced by central differences of the residual (~1e-9).

The derivatives are of the backward-Euler map the Newton iterate satisfies; a step that ended unconverged
(``accept_unconverged``) is differentiated as if it had converged (:attr:`Tape.unconverged` counts them). Not
covered yet (a clear :class:`GradientError`): contact, implicit midpoint, prescribed motion, steps that took the
retry ladder (sub-steps).

Parameters (keys of the tangent / gradient dicts):

    dof0, vel0          (B, n)        the initial DOFs (3-D: the stored frames follow by parallel transport)
                                      and their velocities
    kappa_bar           (T, B, N, 2)  the natural curvature of every step (2-D: column 0)
    tau_bar             (T, B, N)     the natural twist of every step (3-D)
    log_youngs_modulus  (B,)          ln of a factor on every stretching and bending stiffness
    log_shear_modulus   (B,)          ln of a factor on every twisting stiffness
    log_density         (B,)          ln of a factor on every mass (and weight)
    damping             (B,)          the viscous damping rate [1/s]
    gravity             (B, 3)        the gravity vector [m/s²]
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from sim.contact_set import contact_data, contact_scratch
from sim.kernels.data import KL_2D, KL_3D
from sim.kernels.probe import assemble_at

__all__ = ["GradientError", "Tape", "rollout", "PARAMETERS"]

PARAMETERS = ("dof0", "vel0", "kappa_bar", "tau_bar", "log_youngs_modulus", "log_shear_modulus", "log_density",
              "damping", "gravity")


class GradientError(ValueError):
    """A rollout or a request the derivatives do not cover, with what and where."""


def _dense(ab: np.ndarray, n: int, kl: int) -> np.ndarray:
    """The n × n matrix of a full band ab[r, kl + c − r] = J[r, c]."""
    J = np.zeros((n, n))
    for d in range(2 * kl + 1):
        off = d - kl
        r = np.arange(max(0, -off), min(n, n - off))
        J[r, r + off] = ab[r, d]
    return J


@dataclasses.dataclass
class _Lin:
    """One env's step linearised at its solution: J (n, n); the start-state columns F_x, F_u (n,) (diagonal);
    frame maps G (n, E) (∂f/∂φ), a, b (E, n) (φ' = φ + a δx + b δx'); the parameter columns (name -> (n, k))."""

    J: np.ndarray
    Fx: np.ndarray
    Fu: np.ndarray
    G: np.ndarray | None
    a: np.ndarray | None
    b: np.ndarray | None
    P: dict
    lu: tuple | None = None

    def solve(self, rhs: np.ndarray, *, transpose: bool = False) -> np.ndarray:
        """J⁻¹ rhs (or J⁻ᵀ rhs), with J factored once."""
        if self.lu is None:
            self.lu = scipy.linalg.lu_factor(self.J, check_finite=True)
        return scipy.linalg.lu_solve(self.lu, rhs, trans=1 if transpose else 0)


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
    _lin: dict = dataclasses.field(default_factory=dict, repr=False)

    @property
    def steps(self) -> int:
        return self.kappa_bar.shape[0]

    # ------------------------------------------------------------------ linearisation of one step
    def _residual(self, k: int, e: int, x: np.ndarray, *, rod=None, prm=None, kb=None, tb=None):
        sim = self.sim
        rod = self._rod_at(k, e) if rod is None else rod
        prm = sim._prm if prm is None else prm
        kb = self.kappa_bar[k, e] if kb is None else kb
        tb = self.tau_bar[k, e] if tb is None else tb
        n = x.shape[0]
        kl = KL_2D if sim.model.mode == "2d" else KL_3D
        f, ab = np.empty(n), np.empty((n + kl, 2 * kl + 1))
        assemble_at(0, x, self.dof[k, e], self.vel[k, e], self.ref_d1[k, e], self.tangent[k, e],
                     self.ref_twist[k, e], sim.model.dt, np.ascontiguousarray(kb), np.ascontiguousarray(tb), rod, prm,
                     self._cd, f, ab)
        return f, ab

    def _rod_at(self, k: int, e: int, *, free: bool = False):
        """The kernels' rod data of step k of env e (its external forces; ``free``: no DOF constrained)."""
        rod = self.sim._rod._replace(grav=self.grav[k, e][None, :])
        return rod._replace(fixed=np.zeros_like(rod.fixed)) if free else rod

    @property
    def _cd(self):
        sim = self.sim
        if "cd" not in self._lin:
            m = sim.model
            self._lin["cd"] = contact_data(m.obstacles.for_envs(1), contact_scratch(1, m.node_count, 0, m.edge_radius))
        return self._lin["cd"]

    def _linear(self, k: int, e: int, names: tuple[str, ...]) -> _Lin:
        key = (k, e)
        lin = self._lin.get(key)
        if lin is None:
            lin = self._lin[key] = self._linearise(k, e)
        for name in names:
            if name not in lin.P:
                lin.P[name] = self._param_columns(k, e, name)
        return lin

    def _linearise(self, k: int, e: int) -> _Lin:
        sim, m = self.sim, self.sim.model
        h = m.dt
        planar = m.mode == "2d"
        kl = KL_2D if planar else KL_3D
        x1 = self.dof[k + 1, e]
        n = x1.shape[0]
        rod_free = self._rod_at(k, e, free=True)
        _, ab = self._residual(k, e, x1, rod=rod_free)
        Jf = _dense(ab, n, kl)  # ∂f/∂x' with no DOF constrained
        if not planar:
            self._position_columns(k, e, x1, rod_free, Jf)
        fixed = sim._rod.fixed.astype(bool)
        J = Jf.copy()  # constrained DOFs: identity rows and columns (their residual is 0 and they do not move)
        J[fixed, :] = 0.0
        J[:, fixed] = 0.0
        J[fixed, fixed] = 1.0
        mass = sim._rod.mass
        damp = float(sim._prm[0]["damping"])
        pos_dof = np.ones(n, bool) if planar else (np.arange(n) % 4 != 3)
        Fx = -(mass / h**2 + np.where(pos_dof, damp * mass / h, 0.0))
        Fu = -mass / h
        Fx[fixed], Fu[fixed] = 0.0, 0.0
        if planar:
            return _Lin(J, Fx, Fu, None, None, None, {})
        N = n // 4
        E = N - 1
        th = 4 * np.arange(E) + 3
        G = Jf[:, th].copy()
        G[th, np.arange(E)] -= mass[th] / h**2  # ∂f/∂φ: the elastic part of ∂f/∂θ (θ's inertia is not a frame's)
        G[fixed, :] = 0.0
        link = sim._rod.link.astype(bool)
        t0, t1 = self.tangent[k, e], self.tangent[k + 1, e]
        kvec = np.cross(t1, t0) / (1.0 + np.einsum("ij,ij->i", t0, t1))[:, None]
        a = _turn_map(kvec, self.dof[k, e], t0, link)
        b = _turn_map(kvec, x1, t1, link)
        return _Lin(J, Fx, Fu, G, a, b, {})

    def _position_columns(self, k: int, e: int, x1: np.ndarray, rod, Jf: np.ndarray) -> None:
        """Replace the position columns of the 3-D ∂f/∂x' by central differences of the residual (relative error
        ~1e-9). The step's Newton Jacobian is symmetric: it leaves out how the time-parallel reference frames turn
        with the new positions (their holonomy) and some second-order frame terms, which the derivatives need
        (docs/physics.md §3.9); its θ columns are exact and kept."""
        n = x1.shape[0]
        scale = max(1.0, float(np.max(np.abs(x1.reshape(-1, 4)[:, :3]))))
        eps = 1e-6 * scale
        for c in range(n):
            if c % 4 == 3:
                continue
            xp, xm = x1.copy(), x1.copy()
            xp[c] += eps
            xm[c] -= eps
            Jf[:, c] = (self._residual(k, e, xp, rod=rod)[0] - self._residual(k, e, xm, rod=rod)[0]) / (2.0 * eps)

    def _param_columns(self, k: int, e: int, name: str) -> np.ndarray:
        """∂f/∂p (n, k) at step k's solution for the parameter ``name`` (the residual is affine in each: a
        difference of two residuals)."""
        sim, m = self.sim, self.sim.model
        rod = sim._rod
        x1 = self.dof[k + 1, e]
        n = x1.shape[0]
        planar = m.mode == "2d"
        f0, _ = self._residual(k, e, x1)
        fixed = rod.fixed.astype(bool)

        def col(**kw):
            f1, _ = self._residual(k, e, x1, **kw)
            d = f1 - f0
            d[fixed] = 0.0
            return d

        if name == "log_youngs_modulus":  # f = f_rest + E·g: a unit change of ln E doubles... d/d ln E = E·g
            return col(rod=rod._replace(EA=2.0 * rod.EA, EI1=2.0 * rod.EI1, EI2=2.0 * rod.EI2))[:, None]
        if name == "log_shear_modulus":
            return col(rod=rod._replace(GJ=2.0 * rod.GJ))[:, None]
        if name == "log_density":
            grav_rho = np.asarray(m.dof_gravity)[None, :]
            return col(rod=rod._replace(mass=2.0 * rod.mass, grav=rod.grav + grav_rho))[:, None]
        if name == "damping":
            prm = sim._prm.copy()
            prm[0]["damping"] += 1.0
            return col(prm=prm)[:, None]
        if name == "gravity":
            out = np.zeros((n, 3))
            mass = rod.mass
            if planar:
                out[0::2, 0] = -mass[0::2]
                out[1::2, 2] = -mass[1::2]
            else:
                for c in range(3):
                    out[c::4, c] = -mass[c::4]
            out[fixed] = 0.0
            return out
        if name == "kappa_bar":
            kb = self.kappa_bar[k, e]
            N = kb.shape[0]
            cols = np.zeros((n, N * 2))
            for i in range(N):
                for c in range(1 if planar else 2):
                    kb1 = kb.copy()
                    kb1[i, c] += 1.0
                    cols[:, 2 * i + c] = col(kb=kb1)
            return cols
        if name == "tau_bar":
            tb = self.tau_bar[k, e]
            N = tb.shape[0]
            cols = np.zeros((n, N))
            if not planar:
                for i in range(N):
                    tb1 = tb.copy()
                    tb1[i] += 1.0
                    cols[:, i] = col(tb=tb1)
            return cols
        raise GradientError(f"unknown parameter {name!r}; known: {', '.join(PARAMETERS)}")

    # ------------------------------------------------------------------ forward mode
    def jvp(self, tangents: dict | list[dict]) -> dict:
        """Tangents of every state of the rollout for the parameter tangents ``tangents`` (name -> array shaped as
        in the module docstring; absent = 0). Returns {"dof": (T + 1, B, n), "vel": (T + 1, B, n)}; for a list of
        P tangent dicts, arrays (P, T + 1, B, n) (one factorisation per step serves them all)."""
        many = isinstance(tangents, (list, tuple))
        tans = [_checked(t, self) for t in (tangents if many else [tangents])]
        T, B, n = self.steps, self.dof.shape[1], self.dof.shape[2]
        P = len(tans)
        planar = self.sim.model.mode == "2d"
        ddof = np.zeros((P, T + 1, B, n))
        dvel = np.zeros((P, T + 1, B, n))
        h = self.sim.model.dt
        E = self.ref_d1.shape[2]
        names = tuple(sorted({nm for t in tans for nm in t if nm not in ("dof0", "vel0")}))
        zero = np.zeros(n)
        for e in range(B):
            dx = np.stack([t["dof0"][e] if "dof0" in t else zero for t in tans], axis=1)  # (n, P)
            du = np.stack([t["vel0"][e] if "vel0" in t else zero for t in tans], axis=1)
            phi = np.zeros((E, P))
            ddof[:, 0, e], dvel[:, 0, e] = dx.T, du.T
            for k in range(T):
                lin = self._linear(k, e, names)
                rhs = lin.Fx[:, None] * dx + lin.Fu[:, None] * du
                if not planar:
                    rhs += lin.G @ (phi + lin.a @ dx)
                for nm in names:
                    cols = lin.P[nm]
                    for q, t in enumerate(tans):
                        if nm in t:
                            rhs[:, q] += cols @ _param_tangent(t[nm], nm, k, e)
                dx1 = -lin.solve(rhs)
                du = (dx1 - dx) / h
                if not planar:
                    phi = phi + lin.a @ dx + lin.b @ dx1
                dx = dx1
                ddof[:, k + 1, e], dvel[:, k + 1, e] = dx.T, du.T
        if many:
            return {"dof": ddof, "vel": dvel}
        return {"dof": ddof[0], "vel": dvel[0]}

    # ------------------------------------------------------------------ reverse mode
    def vjp(self, cotangents: dict, params=PARAMETERS) -> dict:
        """Gradients of the scalar Σ ⟨cotangent, state⟩ with respect to ``params``; ``cotangents``: "dof" and/or
        "vel", each (T + 1, B, n) (every state of the rollout) or (B, n) (the final state). One backward pass:
        transposed solves with the steps' Jacobians."""
        T, B, n = self.steps, self.dof.shape[1], self.dof.shape[2]
        cx = _cotangent(cotangents.get("dof"), T, B, n)
        cu = _cotangent(cotangents.get("vel"), T, B, n)
        for nm in params:
            if nm not in PARAMETERS:
                raise GradientError(f"unknown parameter {nm!r}; known: {', '.join(PARAMETERS)}")
        planar = self.sim.model.mode == "2d"
        h = self.sim.model.dt
        N = self.tau_bar.shape[2]
        E = self.ref_d1.shape[2]
        out = {nm: np.zeros(_param_shape(nm, T, B, n, N)) for nm in params}
        names = tuple(nm for nm in params if nm not in ("dof0", "vel0"))
        for e in range(B):
            gx = cx[T, e].copy()  # adjoint of x_k (total, including the later steps' dependence)
            gu = cu[T, e].copy()
            gphi = np.zeros(E)
            for k in range(T - 1, -1, -1):
                lin = self._linear(k, e, names)
                # x_{k+1} enters: u_{k+1} = (x_{k+1} − x_k)/h and φ_{k+1} = φ_k + a x_k + b x_{k+1}
                gx1 = gx + gu / h
                if not planar:
                    gx1 = gx1 + lin.b.T @ gphi
                lam = lin.solve(gx1, transpose=True)  # x_{k+1} = −J⁻¹ rhs  ⇒  ∂/∂rhs = −λ
                for nm in names:
                    out[nm] += _param_gradient(-(lin.P[nm].T @ lam), nm, k, e, out[nm])
                gx_prev = -lin.Fx * lam - gu / h + cx[k, e]
                gu_prev = -lin.Fu * lam + cu[k, e]
                if not planar:
                    Gl = -(lin.G.T @ lam)
                    gx_prev = gx_prev + lin.a.T @ (Gl + gphi)
                    gphi = gphi + Gl
                gx, gu = gx_prev, gu_prev
            if "dof0" in out:
                out["dof0"][e] = gx
            if "vel0" in out:
                out["vel0"][e] = gu
        return out


def _turn_map(kvec: np.ndarray, x: np.ndarray, t: np.ndarray, link: np.ndarray) -> np.ndarray:
    """(E, n) map of a change δx of the 3-D DOFs x to kvec_j · δt_j per edge, δt = (I − t tᵀ) δe / |e| (a joint edge
    keeps its frame: 0)."""
    E = t.shape[0]
    n = x.shape[0]
    pos = x.reshape(E + 1, 4)[:, :3]
    le = np.linalg.norm(pos[1:] - pos[:-1], axis=1)
    # row j: w_j · δe_j with w_j = (I − t tᵀ) kvec_j / |e_j|
    w = (kvec - np.einsum("ij,ij->i", t, kvec)[:, None] * t) / le[:, None]
    w[~link] = 0.0
    out = np.zeros((E, n))
    j = np.arange(E)
    for c in range(3):
        out[j, 4 * (j + 1) + c] = w[:, c]
        out[j, 4 * j + c] = -w[:, c]
    return out


def _param_shape(name, T, B, n, N):
    return {"dof0": (B, n), "vel0": (B, n), "kappa_bar": (T, B, N, 2), "tau_bar": (T, B, N),
            "log_youngs_modulus": (B,), "log_shear_modulus": (B,), "log_density": (B,), "damping": (B,),
            "gravity": (B, 3)}[name]


def _param_tangent(v, name, k, e):
    if name == "kappa_bar":
        return v[k, e].reshape(-1)
    if name == "tau_bar":
        return v[k, e]
    if name == "gravity":
        return v[e]
    return np.array([v[e]])


def _param_gradient(g, name, k, e, acc):
    out = np.zeros_like(acc)
    if name == "kappa_bar":
        out[k, e] = g.reshape(acc.shape[2:])
    elif name == "tau_bar":
        out[k, e] = g
    elif name == "gravity":
        out[e] = g
    else:
        out[e] = g[0]
    return out


def _checked(tangents: dict, tape: Tape) -> dict:
    T, B, n = tape.steps, tape.dof.shape[1], tape.dof.shape[2]
    N = tape.tau_bar.shape[2]
    out = {}
    for nm, v in tangents.items():
        if nm not in PARAMETERS:
            raise GradientError(f"unknown parameter {nm!r}; known: {', '.join(PARAMETERS)}")
        arr = np.asarray(v, dtype=np.float64)
        want = _param_shape(nm, T, B, n, N)
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


def rollout(sim, state, controls) -> Tape:
    """Run ``sim`` from ``state`` (advanced in place) for T steps under ``controls`` (a sequence of T
    :class:`sim.Control`, one per step) and record what :class:`Tape` needs to differentiate it. Raises
    :class:`GradientError` for what the derivatives do not cover (contact, implicit midpoint, prescribed motion,
    a step that failed or took the retry ladder)."""
    if int(sim._prm[0]["n_obstacles"]) > 0 or bool(sim._prm[0]["rod_pairs"]):
        raise GradientError("derivatives through contact are not available yet: disable [contact] or remove the "
                            "obstacles and self-contact of this scene")
    if bool(sim._prm[0]["midpoint"]):
        raise GradientError("derivatives of the implicit midpoint rule are not available: use "
                            "integrator = \"backward_euler\"")
    if sim._motion:
        raise GradientError("derivatives with prescribed motion ([[fix]] with a rate) are not available yet")
    controls = list(controls)
    if not controls:
        raise GradientError("rollout needs at least one control (one per step)")
    B = sim.envs
    snap = lambda: (state.dof.reshape(B, -1).copy(), state.dof_vel.reshape(B, -1).copy(),  # noqa: E731
                    state.edge_ref_d1.copy(), state.edge_tangent.copy(), state.node_ref_twist.copy())
    frames = [snap()]
    kbs, tbs, gravs = [], [], []
    unconverged = 0
    for k, ctrl in enumerate(controls):
        gravs.append(sim._external_forces(state.time) if sim._loads else
                     np.broadcast_to(sim._rod.grav, (B, sim._rod.grav.shape[1])).copy())
        kbs.append(np.array(ctrl.kappa_bar, dtype=np.float64))
        tbs.append(np.array(ctrl.tau_bar, dtype=np.float64))
        st = sim.step(state, ctrl)
        bad = np.flatnonzero(st.failed)
        if bad.size:
            raise GradientError(f"step {k}: env {int(bad[0])} failed; a failed step has no derivative")
        sub = np.flatnonzero(st.substeps > 1)
        if sub.size:
            e = int(sub[0])
            raise GradientError(f"step {k}: env {e} took the retry ladder ({int(st.substeps[e])} sub-steps); "
                                "derivatives through sub-steps are not available yet (a smaller dt avoids them)")
        unconverged += int(np.count_nonzero(~st.converged))
        frames.append(snap())
    dof, vel, d1, t, beta = (np.stack(a) for a in zip(*frames))
    return Tape(sim=sim, dof=dof, vel=vel, ref_d1=d1, tangent=t, ref_twist=beta, kappa_bar=np.stack(kbs),
                tau_bar=np.stack(tbs), grav=np.stack(gravs), unconverged=unconverged)
