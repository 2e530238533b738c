"""A model-based baseline for the reaching tasks: inverse statics (``rodlab eval inverse-statics --task T``).

Each control step it asks :func:`sim.analysis.inverse.reach` for the control points' natural curvature that would hold the tip
on the current target at equilibrium (warm-started from its previous answer, a few Gauss–Newton iterations per
control step, the task's bound on |K|), and moves the accumulated curvature toward it as fast as the task's action
allows: a = clip((K* − K) / s_κ, −1, 1). It reads the current K and the target from the observation, and the scene,
control points and smoothing from the task, so it acts through the same converter as a policy. A task that observes a
target orientation and commands twist (4D IK) gets the tip frame too: the twist T* found with the curvature,
a = clip((T* − T) / s_τ, −1, 1). It ignores dynamics (the target's motion, the arm's inertia): a baseline, not an
optimum.
"""
from __future__ import annotations

import numpy as np
from sim.analysis import reach
from sim.geometry import from_xyzw, quat_to_matrix

from .control import smoothing_basis

__all__ = ["InverseStaticsController", "MODEL_BASED"]

MODEL_BASED = ("inverse-statics",)  # controller names `rodlab eval` takes in place of a policy file


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
        off = 0
        self.slices = {}
        for name, size in core.obs_fields:
            self.slices[name] = slice(off, off + int(size))
            off += int(size)
        self.iterations = int(iterations)
        # the tip frame too where the task asks for one and commands twist (4D IK)
        self.oriented = cfg.has_twist and "target_quat" in self.slices and "curr_twist_bar" in self.slices
        self._warm = None

    @classmethod
    def for_env(cls, env, **kw) -> "InverseStaticsController":
        """For an SB3 VecEnv of a rodlab task (``make_sb3_env``)."""
        core = getattr(getattr(env, "venv", None), "core", None)
        if core is None:
            raise ValueError("inverse statics needs a rodlab task env (its core: scene and converter)")
        return cls(core, **kw)

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
