"""3D Random Obstacles: reach a fixed target behind a random fence of 8 capsules (docs/tasks.md §7)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import scenes
from .base import BatchedTask, TaskConfig
from .env import RodTaskEnv
from .obstacles3d import FenceSampler, FenceSpec

__all__ = ["RandomObstacles3DConfig", "RandomObstacles3DCore", "RandomObstacles3DEnv", "default_config"]


@dataclass(frozen=True)
class RandomObstacles3DConfig(TaskConfig):
    """3D Random Obstacles settings: target (x, y, z) [m]; fence: obstacle sampling (count, length,
    radius, box, min_gap, max_trials). Contact: k 1e6, delta 5e-3 m, no friction."""

    substeps: int = 10
    newton_max_iter: int = 5
    timeout_steps: int = 50
    target: tuple[float, float, float] = (0.8, 0.0, 0.35)
    fence: FenceSpec = field(default_factory=FenceSpec)


def default_config() -> RandomObstacles3DConfig:
    """The paper's task (10 sim steps x 5 Newton iterations per 0.5 s control step, 51-step episodes)."""
    return RandomObstacles3DConfig()


class RandomObstacles3DCore(BatchedTask):
    """Batched 3D Random Obstacles core; see :class:`RandomObstacles3DEnv`."""

    control_kind = "contact_bend"

    def __init__(self, config: RandomObstacles3DConfig, *, envs: int = 1, seed: int | None = None):
        if config.mode != "3d":
            raise ValueError("RandomObstacles3DConfig.mode must be '3d'")
        M = config.fence.count
        self.obs_fields = (("curr_kappa_bar", 10), ("obstacle_pos", 6 * M), ("state_pos", 30), ("state_vel", 30),
                           ("target_pos", 3))
        self.sampler = FenceSampler(config.fence)
        # placeholder until the first reset: far away from the arm (x = 10 m), parallel to y
        self.fences = np.zeros((int(envs), M, 2, 3), dtype=np.float32)
        self.fences[..., 0] = 10.0
        self.fences[..., 0, 1], self.fences[..., 1, 1] = -0.5, 0.5
        self.fences[..., 2] = np.arange(M, dtype=np.float32)[:, None] * 0.2
        super().__init__(config, envs=envs, seed=seed)
        self.target = np.broadcast_to(np.asarray(config.target, np.float64), (self.envs, 3))

    def scene_capsules(self) -> tuple[np.ndarray, float]:
        """Placeholder obstacles for building the simulator ((M, 2, 3), radius); re-set per env at reset."""
        return self.fences[0].astype(np.float64), float(self.config.fence.radius)

    def _reset_task(self, idx: np.ndarray) -> None:
        for i in idx:
            self.fences[i] = self.sampler.sample(self.rngs[i])
        scenes.set_env_capsules(self.sim, self.state, idx, self.fences[idx].astype(np.float64),
                                float(self.config.fence.radius))

    def _fields(self) -> dict[str, np.ndarray]:
        f = self.node_fields()
        f["curr_kappa_bar"] = self.converter.kappa_obs
        f["obstacle_pos"] = self.fences.reshape(self.envs, -1)
        f["target_pos"] = self.target
        return f

    def _reward(self, fields):
        return self.reach_terms(fields, self.target)


class RandomObstacles3DEnv(RodTaskEnv):
    """rodlab/RandomObstacles3D-v0: reach (0.8, 0, 0.35) behind a fence of 8 random capsules.

    The fence (8 segments of length 1 m, radius 0.03 m, in x in [0.3, 0.6], y in [-0.6, 0.6],
    z in [-0.1, 0.8], axis distance >= 0.015 m) is re-sampled at every reset with the same
    distribution as the reference (see ``policies.tasks.obstacles3d``); the rod (x = 0) and the target
    (x = 0.8) are clear of it by construction.

    Observation (Box float32, 121), concatenated in this (alphabetical) order:

    ===============  ====  ======================================================
    curr_kappa_bar   10    K per control point, interleaved (kappa1, kappa2)
    obstacle_pos     48    (8, 2, 3) obstacle (start, end) points flattened [m]
    state_pos        30    (x, y, z) of nodes 2, 4, ..., 20 [m]
    state_vel        30    their velocities [m/s]
    target_pos       3     (0.8, 0.0, 0.35) [m]
    ===============  ====  ======================================================

    Action: Box(-1, 1, (10,)) interleaved curvature increments, scale 0.25, K in [-2, 2], ramped over
    the 10 sim steps of the 0.5 s control step.

    Reward: ``-d^2`` (``reward/distance``) + bonus (``reward/bonus``: 2.0 if d < 0.05 m, 0.5 if
    0.05 < d < 0.1), no collision penalty.

    Termination: ``truncated`` after 51 control steps; ``terminated`` with reward -10 on simulator
    failure or reward NaN / < -10.
    """

    core_cls = RandomObstacles3DCore
    config_cls = RandomObstacles3DConfig
