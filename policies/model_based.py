"""Model-based baselines for the reaching tasks: inverse statics (``rodlab eval inverse-statics --task T``) and
receding-horizon trajectory optimisation (``rodlab eval trajectory --task follow_target`` or ``--task ik4d``).

Each control step it asks :func:`sim.analysis.inverse.reach` for the control points' natural curvature that would hold the tip
on the current target at equilibrium (warm-started from its previous answer, a few Gauss–Newton iterations per
control step, the task's bound on |K|), and moves the accumulated curvature toward it as fast as the task's action
allows: a = clip((K* − K) / s_κ, −1, 1). It reads the current K and the target from the observation, and the scene,
control points and smoothing from the task, so it acts through the same converter as a policy. A task that observes a
target orientation and commands twist (4D IK) gets the tip frame too: the twist T* found with the curvature,
a = clip((T* − T) / s_τ, −1, 1). It ignores dynamics (the target's motion, the arm's inertia): a baseline, not an
optimum.

The trajectory controller (:class:`TrajectoryController`) plans the task's own actions over the next ``horizon``
control steps each control step (model-predictive control): the target moving on as it does in the task (its
velocity, reflected at the box's faces; the random turns are unknown to it), the arm stepped by the simulator with
converged Newton steps from the task's current state (all of it, not only the observed nodes: a full-state baseline),
the actions mapped to the natural curvature exactly as the task's converter maps them (control points spread over
their nodes, the increment spread over the sim steps). The objective, Σ_k ‖tip_k − target_k‖² over the control steps'
ends (a static target where the task has no target velocity; on 4D IK + ½ o_k² of the tip frame, the task's smooth
reward, with the twist actions planned too), is minimised by L-BFGS-B in the box |a| ≤ 1 with its gradient from one
adjoint pass (:mod:`sim.analysis.gradients`); the first action is applied, the rest shifted to warm-start the next
plan.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from sim import Simulator, build_model
from sim.analysis import reach, rollout
from sim.geometry import from_xyzw, quat_to_matrix

from .control import smoothing_basis
from .tasks import field_slices

__all__ = ["InverseStaticsController", "TrajectoryController", "MODEL_BASED", "model_based_controller"]

MODEL_BASED = ("inverse-statics", "trajectory")  # controller names `rodlab eval` takes in place of a policy file
# the plan's steps are converged (its derivatives are those of converged steps): tolerances [N], [m/s], iterations
PLAN_NEWTON_TOL, PLAN_NEWTON_DTOL, PLAN_NEWTON_ITER = 1e-9, 1e-9, 20


def _core_of(env):
    core = getattr(getattr(env, "venv", None), "core", None)
    if core is None:
        raise ValueError("a model-based controller needs a rodlab task env (its core: scene and converter)")
    return core


def model_based_controller(name: str, env, **kw):
    """The controller ``name`` (:data:`MODEL_BASED`) for the SB3 VecEnv ``env`` of a rodlab task."""
    if name == "inverse-statics":
        return InverseStaticsController.for_env(env, **kw)
    if name == "trajectory":
        return TrajectoryController(_core_of(env), **kw)
    raise ValueError(f"unknown model-based controller {name!r}; known: {', '.join(MODEL_BASED)}")


class InverseStaticsController:
    """``predict(obs) -> (actions, None)`` like a policy, for the task core ``core`` (a BatchedTask with
    ``curr_kappa_bar`` and ``target_pos`` in its observation)."""

    def __init__(self, core, *, iterations: int = 3):
        names = [n for n, _ in core.obs_fields]
        if "curr_kappa_bar" not in names or "target_pos" not in names:
            raise ValueError(f"inverse statics needs a reaching task (curr_kappa_bar and target_pos in the "
                             f"observation); this one observes {', '.join(names)}")
        cfg = core.converter.cfg
        self.spec = core.model.spec
        self.cfg = cfg
        self.planar = core.planar
        self.plane_y = float(core.model.plane_y) if core.planar else 0.0
        self.basis = smoothing_basis(cfg)
        self.slices = field_slices(core.obs_fields)
        self.iterations = int(iterations)
        # the tip frame too where the task asks for one and commands twist (4D IK)
        self.oriented = cfg.has_twist and "target_quat" in self.slices and "curr_twist_bar" in self.slices
        self._warm = None

    @classmethod
    def for_env(cls, env, **kw) -> "InverseStaticsController":
        """For an SB3 VecEnv of a rodlab task (``make_sb3_env``)."""
        return cls(_core_of(env), **kw)

    def predict(self, obs, deterministic: bool = True):
        obs = np.asarray(obs, dtype=np.float64)
        B = obs.shape[0]
        C = self.cfg.n_components
        K = obs[:, self.slices["curr_kappa_bar"]].reshape(B, self.cfg.n_points, C)
        tgt = obs[:, self.slices["target_pos"]]
        if self.planar:
            tgt = np.stack([tgt[:, 0], np.full(B, self.plane_y), tgt[:, 1]], axis=1)
        warm = self._warm if self._warm is not None and self._warm.coefficients.shape[0] == B else None
        frames = None
        if self.oriented:
            frames = quat_to_matrix(from_xyzw(obs[:, self.slices["target_quat"]]))
        res = reach(self.spec, tgt, basis=self.basis, bound=self.cfg.kappa_limit, max_iterations=self.iterations,
                    warm=warm, orientations=frames, twist_bound=self.cfg.twist_limit)
        self._warm = res
        a = np.clip((res.coefficients - K) / max(self.cfg.kappa_scale, 1e-12), -1.0, 1.0)
        act = a.reshape(B, -1)
        if self.oriented:
            T = obs[:, self.slices["curr_twist_bar"]]
            at = np.clip((res.twist_coefficients - T) / max(self.cfg.twist_scale, 1e-12), -1.0, 1.0)
            act = np.concatenate([act, at], axis=1)
        elif self.cfg.has_twist:  # no twist command: hold the natural twist
            act = np.concatenate([act, np.zeros((B, self.cfg.n_points))], axis=1)
        return act.astype(np.float32), None


class TrajectoryController:
    """``predict(obs) -> (actions, None)`` like a policy: the first action of a plan of ``horizon`` control steps,
    made again every control step (see the module docstring), for the task core ``core`` of a reaching task
    (``target_pos`` observed; a moving target with ``target_vel`` and a target box; with ``target_quat`` and twist
    commands, the tip frame too). ``iterations``: L-BFGS-B iterations per plan; ``effort``: weight of Σ‖a‖² [m²]
    against the squared distances."""

    def __init__(self, core, *, horizon: int = 5, iterations: int = 20, effort: float = 1e-4):
        names = [n for n, _ in core.obs_fields]
        cfg = getattr(core, "config", None)
        if "target_pos" not in names:
            raise ValueError(f"the trajectory controller reaches a target (target_pos in the observation); this task "
                             f"observes {', '.join(names)}")
        self.moving = "target_vel" in names
        if self.moving and not hasattr(cfg, "target_lo"):
            raise ValueError("the trajectory controller follows a moving target inside a target box; this task has "
                             "none")
        if horizon < 1 or iterations < 1 or not effort >= 0.0:
            raise ValueError("trajectory controller: need horizon >= 1, iterations >= 1, effort >= 0")
        self.core, self.cfg = core, core.converter.cfg
        self.horizon, self.iterations, self.effort = int(horizon), int(iterations), float(effort)
        self.slices = field_slices(core.obs_fields)
        self.oriented = self.cfg.has_twist and "target_quat" in self.slices  # the tip frame, by the twist too
        # each planned component's natural-curvature (or twist) change per unit action
        self.scales = np.array([self.cfg.kappa_scale] * self.cfg.n_components
                               + [self.cfg.twist_scale] * (1 if self.oriented else 0))
        spec = core.model.spec
        self.spec = dataclasses.replace(spec, sim=dataclasses.replace(
            spec.sim, newton_tol=PLAN_NEWTON_TOL, newton_dtol=PLAN_NEWTON_DTOL, newton_max_iter=PLAN_NEWTON_ITER))
        if self.moving:
            self.lo, self.hi = np.asarray(cfg.target_lo, float), np.asarray(cfg.target_hi, float)
        self.period = float(core.config.substeps) * float(core.model.dt)
        self.W = smoothing_basis(self.cfg).T  # (P, N) control point -> node weights (the converter's)
        # the share of a control step's increment held at each of its sim steps (the converter's linear ramp)
        S = self.cfg.substeps
        steps = S if self.cfg.temporal_interpolation else 1
        self.ramp = np.minimum(np.arange(1, S + 1), steps) / steps
        self._sim = None
        self._plan = None

    @property
    def components(self) -> int:
        """Planned actions per control point: the curvature's components, and the twist when the tip frame counts."""
        return self.scales.size

    def _targets(self, pos: np.ndarray, vel: np.ndarray | None) -> np.ndarray:
        """(H, B, D) the target at the end of each of the next H control steps: reflected at the box, no turns."""
        if vel is None:
            return np.broadcast_to(pos, (self.horizon,) + pos.shape).copy()
        out, p, v = [], pos.copy(), vel.copy()
        for _ in range(self.horizon):
            v = np.where((p < self.lo) | (p > self.hi), -v, v)
            p = p + v * self.period
            out.append(p)
        return np.stack(out)

    def _schedule(self, A: np.ndarray) -> np.ndarray:
        """(T, B, N, K) the change from now of the natural curvature's components (and twist, the last when
        oriented) at every sim step for the plan A (H, B, P, K)."""
        dK = A * self.scales
        before = np.cumsum(dK, axis=0) - dK  # Σ_{i<k} of the increments
        out = []
        for k in range(self.horizon):
            for share in self.ramp:
                out.append(before[k] + share * dK[k])
        return np.einsum("tbpc,pn->tbnc", np.stack(out), self.W)

    def objective(self, x: np.ndarray, state, kappa0: np.ndarray, targets: np.ndarray, tau0=None,
                  frames=None) -> tuple[float, np.ndarray]:
        """The plan's objective and its gradient at the actions x (H · B · P · K,) from ``state`` under the natural
        curvature ``kappa0`` (B, N, 2) and twist ``tau0`` (B, N) now, for ``targets`` (H, B, D) and, when
        oriented, the target tip frames ``frames`` (B, 3, 3): Σ_k ‖tip_k − target_k‖² (+ ½ o_k², o = 1 − (q·q*)² =
        (3 − tr(R*ᵀ R))/4 as the task's reward) + effort Σ‖a‖²."""
        H, S = self.horizon, self.cfg.substeps
        B, N = kappa0.shape[:2]
        P, C, K = self.cfg.n_points, self.cfg.n_components, self.components
        A = x.reshape(H, B, P, K)
        dk = self._schedule(A)
        ctrls = []
        for t in range(H * S):
            c = self._sim.make_control()
            c.kappa_bar[:] = kappa0
            c.kappa_bar[:, :, :C] += dk[t, ..., :C]
            if self.oriented:
                c.tau_bar[:] = tau0 + dk[t, ..., C]
            ctrls.append(c)
        tape = rollout(self._sim, state.copy(), ctrls)  # (a rollout advances the state it is given)
        planar = self.core.planar
        dpn = 2 if planar else 4
        axes = [dpn * (N - 1) + a for a in range(2 if planar else 3)]
        ends = [(k + 1) * S for k in range(H)]
        tip = tape.dof[ends][:, :, axes]  # (H, B, D)
        r = tip - targets
        cost = float(np.sum(r * r)) + self.effort * float(np.sum(A * A))
        cot = {"dof": np.zeros_like(tape.dof)}
        cot["dof"][np.ix_(ends, np.arange(B), axes)] = 2.0 * r
        if self.oriented:
            cot["phi"] = np.zeros(tape.ref_d1.shape[:3])
            for t in ends:
                o = (3.0 - np.einsum("bij,bij->b", frames, tape.material_frame(t, -1))) / 4.0
                cost += 0.5 * float(np.sum(o * o))
                dof, phi = tape.frame_cotangents(t, -1, -o[:, None, None] * frames / 4.0)
                cot["dof"][t] += dof
                cot["phi"][t] += phi
        grads = tape.vjp(cot, params=("kappa_bar", "tau_bar") if self.oriented else ("kappa_bar",))
        g = grads["kappa_bar"][..., :C]  # (T, B, N, C)
        if self.oriented:
            g = np.concatenate([g, grads["tau_bar"][..., None]], axis=3)
        g_pts = np.einsum("tbnc,pn->tbpc", g, self.W) * self.scales
        gA = np.zeros_like(A)
        for k in range(H):
            for j, share in enumerate(self.ramp):
                t = k * S + j
                gA[:k] += g_pts[t]  # every earlier increment is held by now
                gA[k] += share * g_pts[t]
        return cost, (gA + 2.0 * self.effort * A).reshape(-1)

    def predict(self, obs, deterministic: bool = True):
        import scipy.optimize

        obs = np.asarray(obs, dtype=np.float64)
        core = self.core
        B = obs.shape[0]
        if B != core.envs:
            raise ValueError(f"the trajectory controller plans for the task's {core.envs} envs, got {B} observations")
        if self._sim is None:
            self._sim = Simulator(build_model(self.spec), B)
        H, P, C, K = self.horizon, self.cfg.n_points, self.cfg.n_components, self.components
        vel = obs[:, self.slices["target_vel"]] if self.moving else None
        targets = self._targets(obs[:, self.slices["target_pos"]], vel)
        frames = quat_to_matrix(from_xyzw(obs[:, self.slices["target_quat"]])) if self.oriented else None
        state = core.state.copy()
        kappa0 = np.asarray(core.ctrl.kappa_bar, dtype=np.float64).copy()
        tau0 = np.asarray(core.ctrl.tau_bar, dtype=np.float64).copy()
        x0 = np.zeros((H, B, P, K))
        if self._plan is not None:  # the last plan, a step on
            x0[:-1] = self._plan[1:]
        res = scipy.optimize.minimize(self.objective, x0.reshape(-1), args=(state, kappa0, targets, tau0, frames),
                                      jac=True, method="L-BFGS-B", bounds=[(-1.0, 1.0)] * x0.size,
                                      options={"maxiter": self.iterations})
        self._plan = res.x.reshape(H, B, P, K)
        act = self._plan[0, :, :, :C].reshape(B, -1)
        if self.oriented:
            act = np.concatenate([act, self._plan[0, :, :, C]], axis=1)
        elif self.cfg.has_twist:  # no twist command: hold the natural twist
            act = np.concatenate([act, np.zeros((B, P))], axis=1)
        return act.astype(np.float32), None
