"""4D IK: reach a static position with the tip frame at a target yaw (docs/tasks.md §5)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from .base import BatchedTask, TaskConfig
from .env import RodTaskEnv
from .rewards import ik_reward, orientation_distance
from .targets import matrix_to_quat_xyzw, sample_ik_targets

__all__ = ["IK4DConfig", "IK4DCore", "IK4DEnv", "default_config"]


@dataclass(frozen=True)
class IK4DConfig(TaskConfig):
    """4D IK settings. target_lo / target_hi: target position box [m]; yaw_range: target yaw [rad]."""

    substeps: int = 2
    newton_max_iter: int = 2
    timeout_steps: int = 100
    target_lo: tuple[float, float, float] = (-0.6, -0.6, 0.3)
    target_hi: tuple[float, float, float] = (0.6, 0.6, 0.9)
    yaw_range: tuple[float, float] = (-math.pi / 2, math.pi / 2)


def default_config() -> IK4DConfig:
    """The paper's 4D IK (bend + twist actions, 101-step episodes)."""
    return IK4DConfig()


class IK4DCore(BatchedTask):
    """Batched 4D IK core; see :class:`IK4DEnv`."""

    control_kind = "bend_twist"
    obs_fields = (("curr_kappa_bar", 10), ("curr_twist_bar", 5), ("state_pos", 30), ("state_vel", 30),
                  ("target_pos", 3), ("target_quat", 4), ("tip_orientation", 4))

    def __init__(self, config: IK4DConfig, *, envs: int = 1, seed: int | None = None):
        if config.mode != "3d":
            raise ValueError("IK4DConfig.mode must be '3d' (the task needs twist)")
        super().__init__(config, envs=envs, seed=seed)
        self.target_pos = np.zeros((self.envs, 3))
        self.target_quat = np.zeros((self.envs, 4))
        self.target_quat[:, 3] = 1.0

    def _reset_task(self, idx: np.ndarray) -> None:
        c = self.config
        for i in idx:
            self.target_pos[i], self.target_quat[i] = sample_ik_targets(
                self.rngs[i], lo=c.target_lo, hi=c.target_hi, yaw_range=c.yaw_range)

    def tip_quaternion_xyzw(self) -> np.ndarray:
        """(B, 4) xyzw quaternion of the tip frame (the observation's layout, docs/conventions.md), rotation matrix
        columns (m1, m2, t) of the last edge."""
        st = self.state
        # the simulator's own frame convention, evaluated on the last edge only (cheap for large B)
        last = SimpleNamespace(edge_tangent=st.edge_tangent[:, -1:], edge_ref_d1=st.edge_ref_d1[:, -1:],
                               edge_theta=st.edge_theta[:, -1:])
        m1, m2, t = self.sim.material_frames(last)
        R = np.stack([m1[:, 0], m2[:, 0], t[:, 0]], axis=-1)
        return matrix_to_quat_xyzw(R)

    def _fields(self) -> dict[str, np.ndarray]:
        f = self.node_fields()
        f["curr_kappa_bar"] = self.converter.kappa_obs
        f["curr_twist_bar"] = self.converter.twist_obs
        f["target_pos"] = self.target_pos
        f["target_quat"] = self.target_quat
        f["tip_orientation"] = self.tip_quaternion_xyzw()
        return f

    def _reward(self, fields):
        d = self.obs_tip_distance(fields, self.target_pos)
        o = orientation_distance(fields["tip_orientation"].astype(np.float32).astype(np.float64),
                                 self.target_quat.astype(np.float32).astype(np.float64))
        r, terms = ik_reward(d, o)
        return r, terms, {"tip_distance": d, "orientation_distance": o}


class IK4DEnv(RodTaskEnv):
    """rodlab/IK4D-v0: bring the tip to a static target position with the tip frame at a target yaw.

    Observation (Box float32, 86), concatenated in this (alphabetical) order:

    ================  ====  =============================================================
    curr_kappa_bar    10    accumulated natural curvature K (kappa1, kappa2 per control point)
    curr_twist_bar    5     accumulated natural twist T per control point [rad]
    state_pos         30    (x, y, z) of nodes 2, 4, ..., 20 [m]
    state_vel         30    their velocities [m/s]
    target_pos        3     target position [m] (uniform in [-0.6,0.6]x[-0.6,0.6]x[0.3,0.9])
    target_quat       4     target orientation, xyzw = (0, 0, sin(psi/2), cos(psi/2)), psi ~ U(-pi/2, pi/2)
    tip_orientation   4     xyzw quaternion of (m1, m2, t) of the last edge (SciPy rule, sign not
                            canonicalised; the straight rod gives (0, 0, 1, 0), yaw pi)
    ================  ====  =============================================================

    Action: Box(-1, 1, (15,)): 10 interleaved curvature increments (scale 0.05, K in [-2, 2]) then 5
    twist increments (scale 0.05 rad, T in [-pi/2, pi/2]) of the control points (nodes 2, 6, 10, 14, 18).

    Reward: ``-d^2`` (``reward/distance``) ``- 0.5 o^2`` (``reward/orientation``) + bonus
    (``reward/bonus``, docs/tasks.md §5.5: up to 6 - 2o when d < 0.05 m and o < 0.05), with
    d = tip distance [m] and o = 1 - (q_tip . q_target)^2.

    Termination: ``truncated`` after 101 control steps (0.1 s each); ``terminated`` with reward -10 on
    simulator failure or reward NaN / < -10.
    """

    core_cls = IK4DCore
    config_cls = IK4DConfig
