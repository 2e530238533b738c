"""Static equilibrium (``rodlab sim --static``; docs/physics.md §3.8): pseudo-time continuation with
backward-Euler steps whose step size grows to ``dt_max`` and whose velocities are zeroed before every step.

A backward-Euler step from rest solves ``M (x − x0)/h² + ∇E(x) − F = 0``; as ``h`` grows the inertia term fades
and the step becomes a Newton solve of the static residual ``∇E(x) = F`` regularised by ``M/h²``. Starting from the
scene's ``dt`` and multiplying ``h`` by ``growth`` after every step keeps the first steps small (robust from a far
start); a step whose env fails is undone and retried with ``h`` divided by ``growth``. Each step's Newton solve
ends when an update moves no free position by more than ``xtol · L / 10`` (``L`` the rod length; with several
rods the longest) or by the force
test. Stopping rule, per env: ``h`` has reached ``dt_max`` and the whole step moved no free position DOF by more
than ``xtol · L``: a Newton step on the (barely regularised) static residual then changes nothing at that scale.

The point loads active at each env's time act in full (their windows are not integrated over the pseudo-time),
prescribed motion is off (fixed DOFs stay where the State holds them) and damping is 0.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from sim.analysis.hessian import static_jacobian
from sim.scene.model import build_model
from sim.scene.spec import SceneSpec
from sim.state import STATE_ARRAYS
from sim.step import Simulator

__all__ = ["StaticResult", "static_spec", "solve_static", "static_hessian", "static_stability"]


@dataclasses.dataclass
class StaticResult:
    """Per env (B,): converged, steps taken (all relaxations together), the last step's largest free position change [m] and Newton
    residual; ``dt`` the final pseudo-time step [s]. Stability of the equilibrium found (converged envs; see
    :func:`static_stability`): ``negative_directions`` the number of negative eigenvalues of the static Hessian
    on the free DOFs (0: a local minimum of the energy, stable; more: a saddle or maximum, unstable; -1: not
    checked), ``stable`` whether it is 0, ``lowest_eigenvalue`` [1/s²] the lowest eigenvalue of the
    mass-weighted Hessian ``M^-1/2 H M^-1/2`` (nan: not checked); ``perturbations`` how many times ``to_stable``
    pushed the env along a negative direction."""

    converged: np.ndarray
    steps: np.ndarray
    last_move: np.ndarray
    residual: np.ndarray
    dt: float
    stable: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, bool))
    negative_directions: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))
    lowest_eigenvalue: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    perturbations: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))


def static_spec(spec: SceneSpec, time: float, dt: float, dx_stop: float) -> SceneSpec:
    """The spec of a static pseudo-step of size ``dt`` at ``time``: loads active at ``time`` always on, no
    prescribed motion, no damping, backward Euler with backtracking; its Newton solve stops when an update moves
    no free position by more than ``dx_stop`` [m] (or by the force test)."""
    loads = tuple(dataclasses.replace(ld, start=0.0, stop=None) for ld in spec.loads
                  if ld.start <= time < (math.inf if ld.stop is None else ld.stop))
    fixes = tuple(dataclasses.replace(fx, velocity=(0.0, 0.0, 0.0), twist_rate=0.0, angular_velocity=(0.0, 0.0, 0.0),
                                      start=0.0, stop=None) for fx in spec.fixes)
    sim = dataclasses.replace(spec.sim, dt=dt, damping=0.0, integrator="backward_euler", line_search="backtrack",
                              newton_dtol=max(dx_stop / dt, 1e-300), newton_tol=min(spec.sim.newton_tol, 1e-10),
                              newton_max_iter=max(spec.sim.newton_max_iter, 50), accept_unconverged=True)
    return dataclasses.replace(spec, sim=sim, loads=loads, fixes=fixes)


def solve_static(spec: SceneSpec, state: Any, ctrl: Any, *, xtol: float = 1e-10, dt_max: float = 1e5,
                 growth: float = 10.0, max_steps: int = 200, check_stability: bool = True, to_stable: bool = False,
                 max_tries: int = 4) -> StaticResult:
    """Relax ``state`` (of a Simulator of ``spec``; changed in place) to static equilibrium under ``ctrl``.

    All envs share the pseudo-time step; envs that have converged keep stepping (their moves stay below the
    tolerance). ``state.time`` is left unchanged.

    ``check_stability``: count the negative directions of the static Hessian at each converged env's equilibrium
    (:func:`static_stability`). A saddle satisfies ``∇E = F`` as well as a minimum, and Newton converges to
    whichever is near (a column under twice its buckling load stays straight). ``to_stable``: while an env is at
    an unstable equilibrium (at most ``max_tries`` times), push it along the eigenvector of the lowest eigenvalue
    (largest node move 1 %, then 10 %, 30 %, ... of the rod length), relax it with a fixed pseudo-time step
    ``h = sqrt(0.5/|λ|)`` (an energy-decreasing proximal step that the negative direction cannot turn back up: the
    perturbation doubles per step) and then with the growing steps above, and check again."""
    if not (xtol > 0 and dt_max >= spec.sim.dt and growth > 1 and max_steps >= 1 and max_tries >= 0):
        raise ValueError("solve_static: need xtol > 0, dt_max >= the scene's dt, growth > 1, max_steps >= 1, "
                         "max_tries >= 0")
    B = state.dof.shape[0]
    t = float(state.time[0]) if B else 0.0
    if B and not np.all(state.time == t):
        raise ValueError("solve_static: all envs must be at the same time (the active loads depend on it)")
    time0 = state.time.copy()
    length = max(float(r.length) for r in spec.rods)
    run = _Relax(spec, state, ctrl, t, xtol * length, dt_max, growth)
    res = run(float(spec.sim.dt), 0, max_steps)
    neg = np.full(B, -1, np.int64)
    lam = np.full(B, np.nan)
    pushed = np.zeros(B, np.int64)
    if check_stability or to_stable:
        neg, lam, vec = _stability(run.any_sim(), state, ctrl, res.converged)
        for k in range(max_tries if to_stable else 0):
            bad = res.converged & (neg > 0)
            if not bad.any():
                break
            _push(run.any_sim().model, state, vec, bad, length * (0.01 if k == 0 else 0.1 * 3.0 ** (k - 1)))
            pushed += bad
            h_hold = float(np.sqrt(0.5 / np.max(-lam[bad])))
            steps = res.steps
            res = run(h_hold, 100, max_steps)
            res.steps += steps
            neg, lam, vec = _stability(run.any_sim(), state, ctrl, res.converged)
    state.dof_vel[...] = 0.0
    state.time[:] = time0
    res.negative_directions, res.lowest_eigenvalue, res.perturbations = neg, lam, pushed
    res.stable = res.converged & (neg == 0)
    return res


class _Relax:
    """The pseudo-time continuation of :func:`solve_static` on one state (the Simulators by step size kept)."""

    def __init__(self, spec, state, ctrl, t, move_tol, dt_max, growth):
        self.spec, self.state, self.ctrl, self.t = spec, state, ctrl, t
        self.move_tol, self.dt_max, self.growth = move_tol, dt_max, growth
        self.sims: dict[float, Simulator] = {}
        self.free = None

    def sim(self, h: float) -> Simulator:
        if h not in self.sims:
            spec = static_spec(self.spec, self.t, h, 0.1 * self.move_tol)
            self.sims[h] = Simulator(build_model(spec), envs=self.state.dof.shape[0])
        return self.sims[h]

    def any_sim(self) -> Simulator:
        return next(iter(self.sims.values())) if self.sims else self.sim(float(self.spec.sim.dt))

    def __call__(self, h: float, hold: int, max_steps: int) -> StaticResult:
        """From pseudo-time step ``h``: ``hold`` steps at ``h`` (fewer once a step moves less than 1e-3 of the
        largest move so far), then ``h`` grows by ``growth`` per step up to ``dt_max`` until converged."""
        state, ctrl, spec = self.state, self.ctrl, self.spec
        B = state.dof.shape[0]
        conv = np.zeros(B, bool)
        steps = np.zeros(B, np.int64)
        move = np.full(B, np.inf)
        res = np.full(B, np.inf)
        h_min = min(float(spec.sim.dt), h)
        largest = 0.0
        h_fail = np.inf  # the step size that failed last (a singular static Hessian: a neutral direction)
        for _ in range(max_steps + hold):
            sim = self.sim(h)
            if self.free is None:
                m = sim.model
                dpn = m.dofs_per_node
                pos_dof = (np.arange(m.node_count * dpn) % dpn) < (3 if dpn == 4 else 2)
                self.free = np.flatnonzero(pos_dof & ~m.dof_fixed)
            free = self.free
            before = state.copy()
            state.dof_vel[...] = 0.0
            stats = sim.step(state, ctrl)
            if state.failed.any():  # undo the step in every env and shrink the pseudo-time step
                _restore(state, before)
                if h <= h_min:
                    break
                h_fail = h
                h = max(h_min, h / self.growth)
                hold = 0
                continue
            steps += 1
            d = np.abs(state.dof.reshape(B, -1)[:, free] - before.dof.reshape(B, -1)[:, free])
            move = d.max(axis=1) if free.size else np.zeros(B)
            res = stats.residual
            if hold > 0:
                hold -= 1
                largest = max(largest, float(move.max(initial=0.0)))
                if float(move.max(initial=0.0)) < 1e-3 * largest:
                    hold = 0
                continue
            # converged: no move at the largest step, or at the largest step that still factorises (a neutral
            # direction, e.g. the plane of a buckled round column, makes the barely regularised Jacobian singular)
            top = h >= self.dt_max or (h * self.growth >= h_fail and h >= 1e-3 * self.dt_max)
            conv = top & (move <= self.move_tol)
            if conv.all():
                break
            h = min(self.dt_max, h * self.growth)
        return StaticResult(converged=conv, steps=steps, last_move=move, residual=np.asarray(res), dt=h)


def _static_band(sim: Simulator, state: Any, ctrl: Any, e: int):
    """Env ``e``'s static Jacobian as the kernel gives it: the band (n + kl, 2 kl + 1) (row r, column c at
    [r, kl + c − r]), and the out-of-band coupling of touching edge pairs (its DOFs (K,) and dense block (K, K))."""
    B = state.dof.shape[0]
    return static_jacobian(e, np.ascontiguousarray(state.dof.reshape(B, -1)[e]),
                           np.ascontiguousarray(state.edge_ref_d1[e]), np.ascontiguousarray(state.edge_tangent[e]),
                           np.ascontiguousarray(state.node_ref_twist[e]),
                           np.ascontiguousarray(ctrl.kappa_bar[e], dtype=np.float64),
                           np.ascontiguousarray(ctrl.tau_bar[e], dtype=np.float64), sim.kernel_rod, sim.kernel_params,
                           sim.contact_data(state))


def _band_entries(ab: np.ndarray, n: int):
    """(rows, columns, values) of the entries of a band (n + kl, 2 kl + 1) inside the (n, n) matrix."""
    kl = (ab.shape[1] - 1) // 2
    r = np.arange(n)[:, None]
    c = r + np.arange(-kl, kl + 1)[None, :]
    ok = (c >= 0) & (c < n)
    return np.broadcast_to(r, c.shape)[ok], c[ok], ab[:n][ok]


def static_hessian(sim: Simulator, state: Any, ctrl: Any, e: int) -> np.ndarray:
    """The dense (n, n) static Hessian of env ``e`` at its state (constrained DOFs: identity rows and columns), the
    step's own elements at the state's frames, where they are exact (docs/physics.md §2.4); friction, not a
    potential force, is left out by taking the symmetric part."""
    ab, dofs, cm = _static_band(sim, state, ctrl, e)
    n = state.dof.reshape(state.dof.shape[0], -1).shape[1]
    H = np.zeros((n, n))
    r, c, v = _band_entries(ab, n)
    H[r, c] = v
    if dofs.size:
        H[np.ix_(dofs, dofs)] += cm
    return 0.5 * (H + H.T)


ROUNDING_TOL = 1e-14  # eigenvalues within this fraction of max |diag S| of 0 are rounding (negative_threshold)
NEUTRAL_TOL = 1e-3    # ... and within this fraction of the rod's bending scale EI/(ρA L⁴) of 0 are neutral


def negative_threshold(model: Any, max_diag: float) -> float:
    """The size [1/s²] below −which an eigenvalue of the mass-weighted static Hessian ``S`` counts as a negative
    direction: the larger of ``ROUNDING_TOL`` times ``S``'s largest diagonal entry ``max_diag`` (the rounding of the
    eigensolver; that entry grows with the stiffest mode, EI/(ρA l⁴) ∝ N⁴) and ``NEUTRAL_TOL`` times the rod's
    bending scale min EI / (max ρA · L⁴) (the softest bending mode's order of magnitude), under which an eigenvalue
    is a neutral direction solved to the static tolerance (the turn of a round column's buckling plane about its
    axis comes out at ≈ −5e-5 of that scale), not an instability."""
    ei = np.minimum(np.asarray(model.node_EI1), np.asarray(model.node_EI2))
    rho_a = np.asarray(model.node_mass) / np.maximum(np.asarray(model.voronoi_length), 1e-300)
    length = max(float(r.length) for r in model.spec.rods)
    pos = ei[ei > 0]
    bend = float(pos.min()) / (float(rho_a.max()) * length ** 4) if pos.size and rho_a.max() > 0 else 0.0
    return max(ROUNDING_TOL * float(max_diag), NEUTRAL_TOL * bend)


_DENSE_BELOW = 64  # free DOFs below which the dense eigensolver is used (as cheap as the banded one there)


def _banded_lowest(band: np.ndarray, S, w0: float, c: int, gap: float, scale: float) -> np.ndarray:
    """(n, c) orthonormal basis of the eigenspace of the ``c`` lowest eigenvalues (the lowest ``w0``) of the symmetric
    banded ``S`` (``band``: its upper band form, ``S`` the same matrix as a sparse one) by block inverse iteration: a
    shift ``σ`` below ``w0`` by a thousandth of the ``gap`` to the next eigenvalue makes ``S − σI`` positive definite
    (a banded Cholesky factor, O(n kl²)), and each solve shrinks the other eigenvectors' parts by about 1e-3; a
    Rayleigh–Ritz step orders the block."""
    from scipy.linalg import cho_solve_banded, cholesky_banded, eigh

    kl = band.shape[0] - 1
    shifted = band.copy()
    delta = max(1e-3 * gap, 1e-12 * scale)  # above the eigenvalues' rounding (~1e-16 of the scale)
    for _ in range(4):  # a shift the rounding of w0 put above it: further down
        shifted[:] = band
        shifted[kl] -= w0 - delta
        try:
            cb = cholesky_banded(shifted, lower=False)
            break
        except np.linalg.LinAlgError:
            delta *= 10.0
    else:
        raise np.linalg.LinAlgError("banded Cholesky of the shifted static Hessian failed")
    x = np.random.default_rng(0).standard_normal((band.shape[1], c))
    for _ in range(12):
        x = cho_solve_banded((cb, False), x)
        x, _r = np.linalg.qr(x)
    h = x.T @ (S @ x)
    _, q = eigh(0.5 * (h + h.T))
    return x @ q


def static_stability(sim: Simulator, state: Any, ctrl: Any, e: int) -> tuple[int, float, np.ndarray]:
    """(negative directions, lowest eigenvalue [1/s²], its eigenvector (n,)) of env ``e``'s equilibrium.

    The eigenproblem is the mass-weighted static Hessian ``S = M^-1/2 H M^-1/2`` on the free DOFs (``M`` the
    lumped DOF masses); by Sylvester's law of inertia ``S`` has as many negative eigenvalues as ``H``, and its
    lowest eigenvector (mapped back by ``M^-1/2``) is the direction a pseudo-time step grows fastest along. A
    symmetric eigensolver is used rather than the signs of the step's LDLᵀ pivots: those are not exposed by the
    kernel, belong to an iterate before the last one, and an LDLᵀ without pivoting can break down on an
    indefinite matrix. ``S`` keeps the Hessian's band (removing constrained DOFs narrows it): its eigenvalues come
    from the banded symmetric eigensolver (O(n² kl), no eigenvectors) and the lowest eigenvectors from block inverse
    iteration with a banded Cholesky factor (:func:`_banded_lowest`, O(n kl²)), instead of the O(n³) of a dense
    solve; with edge pairs in touch (couplings outside the band), or few DOFs, the dense solver is used. Eigenvalues
    below ``-negative_threshold`` count as negative: not rounding nor a neutral direction (a tolerance of 1e-9 of the
    largest diagonal entry, which grows with N⁴, hid the buckling modes of fine rods: the column at twice its Euler
    load read stable from about 300 nodes on). Where the lowest eigenvalue is multiple, the eigenvector
    returned is the combination of its eigenvectors nearest to moving every free node down (−z)."""
    import scipy.sparse as sp
    from scipy.linalg import eig_banded

    m = sim.model
    ab, dofs, cm = _static_band(sim, state, ctrl, e)
    n = state.dof.reshape(state.dof.shape[0], -1).shape[1]
    free = np.flatnonzero(~np.asarray(m.dof_fixed))
    d = 1.0 / np.sqrt(np.asarray(m.dof_mass)[free])
    nf = free.size
    if dofs.size or nf < _DENSE_BELOW:
        H = static_hessian(sim, state, ctrl, e)
        S = H[np.ix_(free, free)] * d[:, None] * d[None, :]
        thr = negative_threshold(m, float(np.abs(np.diag(S)).max(initial=0.0)))
        w, v = np.linalg.eigh(S)
        deg = v[:, np.abs(w - w[0]) <= 1e-6 * abs(w[0])] if w.size else v[:, :1]
    else:
        kl = (ab.shape[1] - 1) // 2
        r, c, val = _band_entries(ab, n)
        Hs = sp.coo_matrix((val, (r, c)), shape=(n, n)).tocsr()
        Hs = 0.5 * (Hs + Hs.T)
        D = sp.diags(d)
        S = (D @ Hs[free][:, free] @ D).tocsr()
        band = np.zeros((kl + 1, nf))   # upper form: band[kl + i − j, j] = S[i, j], i ≤ j
        for k in range(kl + 1):
            band[kl - k, k:] = S.diagonal(k)
        thr = negative_threshold(m, float(np.abs(band[kl]).max(initial=0.0)))
        w = eig_banded(band, eigvals_only=True)
        cl = int(np.count_nonzero(np.abs(w - w[0]) <= 1e-6 * abs(w[0])))  # the lowest eigenvalue's multiplicity
        gap = float(w[cl] - w[0]) if cl < nf else float(np.abs(w).max())
        deg = _banded_lowest(band, S, float(w[0]), cl, gap, float(np.abs(w).max()))
        v = deg
    # a multiple lowest eigenvalue (a round column buckles in any plane): of its eigenvectors, the combination
    # nearest to moving every free node down (-z), so that the push keeps a plane of symmetry where there is one
    dpn = m.dofs_per_node
    down = -((free % dpn) == (2 if dpn == 4 else 1)).astype(float)
    y = deg @ (deg.T @ down)
    y = y if np.linalg.norm(y) > 1e-8 * np.linalg.norm(down) else v[:, 0]
    vec = np.zeros(n)
    vec[free] = d * y / np.linalg.norm(y)
    return int(np.count_nonzero(w < -thr)), float(w[0]), vec


def _stability(sim, state, ctrl, conv):
    B = state.dof.shape[0]
    neg = np.full(B, -1, np.int64)
    lam = np.full(B, np.nan)
    vec = np.zeros((B, state.dof.reshape(B, -1).shape[1]))
    for e in np.flatnonzero(conv):
        neg[e], lam[e], vec[e] = static_stability(sim, state, ctrl, int(e))
    return neg, lam, vec


def _push(model, state, vec, envs, size):
    """Move the ``envs`` along ``vec`` (B, n) so that the largest node displacement is ``size`` [m] (the sign
    that moves the lowest free node down: under gravity the way a buckle or a sagging rope goes)."""
    B = state.dof.shape[0]
    dpn = model.dofs_per_node
    npos = 3 if dpn == 4 else 2
    q = state.dof.reshape(B, -1)
    for e in np.flatnonzero(envs):
        v = vec[e].reshape(-1, dpn)
        s = np.abs(v[:, :npos]).max()
        if s > 0:
            q[e] += (size / s) * vec[e] * (1.0 if v[:, npos - 1].sum() <= 0 else -1.0)


def _restore(state: Any, before: Any) -> None:
    for name in STATE_ARRAYS:
        getattr(state, name)[...] = getattr(before, name)
