"""Follow Target (3D) and its 2D variant (docs/tasks.md §4)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import BatchedTask, TaskConfig
from .env import RodTaskEnv
from .targets import FollowTargetMotion

__all__ = ["FollowTargetConfig", "FollowTargetCore", "FollowTargetEnv", "FollowTarget2DEnv",
           "default_config", "default_config_2d"]


@dataclass(frozen=True)
class FollowTargetConfig(TaskConfig):
    """Follow Target settings (defaults = the paper's 3D task; see :func:`default_config_2d`).

    target_lo / target_hi: target box [m] ((x, y, z) in 3D, (x, z) in 2D); target_speed v0 [m/s];
    direction_change_prob: per-control-step probability of a new random direction.
    """

    substeps: int = 2
    newton_max_iter: int = 2
    timeout_steps: int = 500
    target_lo: tuple[float, ...] = (-0.6, -0.6, 0.3)
    target_hi: tuple[float, ...] = (0.6, 0.6, 0.9)
    target_speed: float = 0.5
    direction_change_prob: float = 0.025


def default_config() -> FollowTargetConfig:
    """The paper's 3D Follow Target (dt 0.05, 2 sim steps x 2 Newton iterations, 501-step episodes)."""
    return FollowTargetConfig()


def default_config_2d() -> FollowTargetConfig:
    """The paper's 2D Follow Target (x-z plane, simulator mode "2d")."""
    return FollowTargetConfig(mode="2d", scene="assets/scenes/arm_2d.toml", target_lo=(-0.6, 0.3),
                              target_hi=(0.6, 0.9))


class FollowTargetCore(BatchedTask):
    """Batched Follow Target core (3D or 2D by ``config.mode``); see :class:`FollowTargetEnv`."""

    def __init__(self, config: FollowTargetConfig, *, envs: int = 1, seed: int | None = None):
        self.dim = 2 if config.mode == "2d" else 3
        if len(config.target_lo) != self.dim or len(config.target_hi) != self.dim:
            raise ValueError(f"FollowTargetConfig: target_lo/target_hi must have {self.dim} entries in mode "
                             f"{config.mode!r}, got {config.target_lo}, {config.target_hi}")
        D = self.dim
        self.control_kind = "bend_2d" if D == 2 else "bend"
        self.obs_fields = (("curr_kappa_bar", 5 * (D - 1)), ("state_pos", 10 * D), ("state_vel", 10 * D),
                           ("target_pos", D), ("target_vel", D))
        super().__init__(config, envs=envs, seed=seed)
        self.target = FollowTargetMotion(
            self.envs, dim=D, lo=config.target_lo, hi=config.target_hi, speed=config.target_speed,
            p_change=config.direction_change_prob, dt=config.dt * config.substeps,
            horizon=config.timeout_steps + 1)

    def _reset_task(self, idx: np.ndarray) -> None:
        self.target.reset(idx, self.rngs)

    def _post_step(self) -> None:
        self.target.advance()

    def _fields(self) -> dict[str, np.ndarray]:
        f = self.node_fields()
        f["curr_kappa_bar"] = self.converter.kappa_obs
        f["target_pos"] = self.target.pos
        f["target_vel"] = self.target.vel
        return f

    def _reward(self, fields):
        return self.reach_terms(fields, self.target.pos)


class FollowTargetEnv(RodTaskEnv):
    """rodlab/FollowTarget-v0: track a target moving at 0.5 m/s in a box with the arm's tip (3D).

    Observation (Box float32, 76), concatenated in this (alphabetical) order:

    =================  ====  ==========================================================
    curr_kappa_bar     10    accumulated natural curvature K per control point, interleaved
                             (kappa1_0, kappa2_0, ..., kappa2_4) [dimensionless, integrated]
    state_pos          30    (x, y, z) of nodes 2, 4, ..., 20 [m] (tip = last 3)
    state_vel          30    their velocities [m/s]
    target_pos         3     target position after this step's motion update [m]
    target_vel         3     target velocity [m/s]
    =================  ====  ==========================================================

    Action: Box(-1, 1, (10,)) interleaved (kappa1, kappa2) increments of the 5 control points
    (nodes 2, 6, 10, 14, 18); scale 0.05 per step, K clipped to [-2, 2]; ramped over the 2 sim steps.

    Reward: ``-d^2`` (``reward/distance``) + bonus (``reward/bonus``: 2.0 if d < 0.05 m, 0.5 if
    0.05 < d < 0.1, else 0), d = tip-to-target distance [m] (``tip_distance``).

    Termination: ``truncated`` after 501 control steps (timeout_steps = 500, 0.1 s each);
    ``terminated`` with reward -10 on simulator failure or reward NaN / < -10 (``failure_reason``).
    """

    core_cls = FollowTargetCore
    config_cls = FollowTargetConfig


class FollowTarget2DEnv(RodTaskEnv):
    """rodlab/FollowTarget2D-v0: Follow Target in the x-z plane (simulator mode "2d").

    Observation (Box float32, 49), in this order: ``curr_kappa_bar`` 5 (K per control point);
    ``state_pos`` 20 ((x, z) of nodes 2, 4, ..., 20 [m]); ``state_vel`` 20 [m/s]; ``target_pos`` 2 [m];
    ``target_vel`` 2 [m/s] (direction (cos a sin b, cos b) * 0.5, not normalised as in the paper).

    Action: Box(-1, 1, (5,)) in-plane curvature increments (scale 0.05, K in [-2, 2]), ramped over
    the 2 sim steps; positive values bend the upright arm toward -x.

    Reward: ``-d^2`` (``reward/distance``) + bonus (``reward/bonus``: 2.0 if d < 0.05 m, 0.5 if
    0.05 < d < 0.1), d = 2D tip-to-target distance [m].

    Termination: ``truncated`` after 501 control steps; ``terminated`` with reward -10 on simulator
    failure or reward NaN / < -10.
    """

    core_cls = FollowTargetCore
    config_cls = FollowTargetConfig

    def __init__(self, config: FollowTargetConfig | None = None, **kw):
        super().__init__(default_config_2d() if config is None else config, **kw)
