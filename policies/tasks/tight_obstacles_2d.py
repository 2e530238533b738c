"""2D Tight Obstacles: planar reach through a narrow crevice of fixed discs (docs/tasks.md §6)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import BatchedTask, TaskConfig
from .env import RodTaskEnv

__all__ = ["TightObstacles2DConfig", "TightObstacles2DCore", "TightObstacles2DEnv", "default_config",
           "CREVICE"]

#: (x, z) centres [m] of the six obstacles (axis parallel to y, y in [-0.5, 0.5], radius 0.1 m)
CREVICE: tuple[tuple[float, float], ...] = ((0.2, 0.12), (0.6, 0.12), (0.4, 0.0), (0.4, 0.37), (0.4, 0.57),
                                            (0.4, 0.77))


@dataclass(frozen=True)
class TightObstacles2DConfig(TaskConfig):
    """2D Tight Obstacles settings. obstacle_centres (x, z) [m], obstacle_radius [m], obstacle_half_length
    (half extent along y) [m], target (x, z) [m]. Contact: k 1e6, delta 5e-3 m, no friction."""

    substeps: int = 10
    newton_max_iter: int = 5
    mode: str = "2d"
    timeout_steps: int = 50
    scene: str | None = "assets/scenes/tight_obstacles_2d.toml"
    obstacle_centres: tuple[tuple[float, float], ...] = CREVICE
    obstacle_radius: float = 0.1
    obstacle_half_length: float = 0.5
    target: tuple[float, float] = (0.8, 0.15)

    def capsules(self) -> np.ndarray:
        """(M, 2, 3) capsule axis end-points [m] of the obstacles."""
        c = np.asarray(self.obstacle_centres, float)
        h = self.obstacle_half_length
        return np.stack([np.stack([c[:, 0], np.full(len(c), -h), c[:, 1]], -1),
                         np.stack([c[:, 0], np.full(len(c), h), c[:, 1]], -1)], axis=1)


def default_config() -> TightObstacles2DConfig:
    """The paper's task (10 sim steps x 5 Newton iterations per 0.5 s control step, 51-step episodes)."""
    return TightObstacles2DConfig()


class TightObstacles2DCore(BatchedTask):
    """Batched 2D Tight Obstacles core; see :class:`TightObstacles2DEnv`."""

    control_kind = "contact_bend_2d"
    fixed_obstacles = True
    obs_fields = (("curr_kappa_bar", 5), ("state_pos", 20), ("state_vel", 20), ("target_pos", 2))

    def __init__(self, config: TightObstacles2DConfig, *, envs: int = 1, seed: int | None = None):
        if config.mode != "2d":
            raise ValueError("TightObstacles2DConfig.mode must be '2d'")
        super().__init__(config, envs=envs, seed=seed)
        self.target = np.broadcast_to(np.asarray(config.target, np.float64), (self.envs, 2))

    def scene_capsules(self) -> tuple[np.ndarray, float]:
        """Obstacles for the scene built in code: ((M, 2, 3) end-points [m], radius [m])."""
        return self.config.capsules(), float(self.config.obstacle_radius)

    def _fields(self) -> dict[str, np.ndarray]:
        f = self.node_fields()
        f["curr_kappa_bar"] = self.converter.kappa_obs
        f["target_pos"] = self.target
        return f

    def _reward(self, fields):
        return self.reach_terms(fields, self.target)


class TightObstacles2DEnv(RodTaskEnv):
    """rodlab/TightObstacles2D-v0: planar reach to (0.8, 0.15) through a crevice of six fixed discs.

    Nothing is random (fixed start, obstacles, target). Obstacles: discs of radius 0.1 m at (x, z) =
    (0.2, 0.12), (0.6, 0.12), (0.4, 0.0), (0.4, 0.37), (0.4, 0.57), (0.4, 0.77) (capsules along y).

    Observation (Box float32, 47), in this order: ``curr_kappa_bar`` 5 (K per control point);
    ``state_pos`` 20 ((x, z) of nodes 2, 4, ..., 20 [m]); ``state_vel`` 20 [m/s]; ``target_pos`` 2 [m].

    Action: Box(-1, 1, (5,)) in-plane curvature increments, scale 0.25 per step, K in [-2, 2], ramped
    over the 10 sim steps of the 0.5 s control step.

    Reward: ``-d^2`` (``reward/distance``) + bonus (``reward/bonus``: 2.0 if d < 0.05 m, 0.5 if
    0.05 < d < 0.1), no contact penalty.

    Termination: ``truncated`` after 51 control steps; ``terminated`` with reward -10 on simulator
    failure or reward NaN / < -10.
    """

    core_cls = TightObstacles2DCore
    config_cls = TightObstacles2DConfig
