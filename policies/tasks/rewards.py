"""Reward functions of the four tasks (docs/tasks.md §4.4, §5.5, §6.4, §7.4), vectorised over envs.

All take arrays with a leading batch axis and return float64 arrays of shape (B,) plus a dict of
named terms (each (B,)), which the envs put into ``info`` as ``reward/<term>``.
Band edges follow the reference exactly: d = 0.05 gets no bonus, d = 0.1 gets no bonus.
"""
from __future__ import annotations

import numpy as np

__all__ = ["reach_reward", "ik_reward", "orientation_distance", "FAILURE_REWARD"]

#: reward of a failed control step (simulator failure or reward explosion), docs/tasks.md §3.3
FAILURE_REWARD = -10.0


def reach_reward(d: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Follow / obstacle reward: ``r = -d^2 + b(d)``, b = 2.0 if d < 0.05, 0.5 if 0.05 < d < 0.1, else 0.

    d: (B,) tip-to-target distance [m]. Returns (r, {"distance": -d^2, "bonus": b}).
    """
    d = np.asarray(d, dtype=np.float64)
    dist = -(d * d)
    bonus = np.where(d < 0.05, 2.0, np.where((d > 0.05) & (d < 0.1), 0.5, 0.0))
    return dist + bonus, {"distance": dist, "bonus": bonus}


def orientation_distance(q_tip: np.ndarray, q_target: np.ndarray) -> np.ndarray:
    """o = 1 - (q_tip . q_target)^2 in [0, 1] (sign-invariant); quaternions (B, 4), any convention."""
    dot = np.sum(np.asarray(q_tip, np.float64) * np.asarray(q_target, np.float64), axis=-1)
    return np.clip(1.0 - dot * dot, 0.0, 1.0)


def ik_reward(d: np.ndarray, o: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """4D IK reward: ``r = -d^2 - 0.5 o^2 + bonus(d, o)`` (docs/tasks.md §5.5 table).

    d: (B,) distance [m]; o: (B,) orientation distance in [0, 1].
    Returns (r, {"distance": -d^2, "orientation": -0.5 o^2, "bonus": bonus}).
    """
    d = np.asarray(d, dtype=np.float64)
    o = np.asarray(o, dtype=np.float64)
    near = d < 0.05
    mid = (d > 0.05) & (d < 0.1)
    bonus_mid = np.where(o > 0.1, 1.0 - 0.5 * o, 1.5 - 0.5 * o)
    bonus_near = np.where(o > 0.1, 4.0 - 2.0 * o, np.where(o >= 0.05, 4.5 - 2.0 * o, 6.0 - 2.0 * o))
    bonus = np.where(near, bonus_near, np.where(mid, bonus_mid, 0.0))
    dist = -(d * d)
    ori = -0.5 * o * o
    return dist + ori + bonus, {"distance": dist, "orientation": ori, "bonus": bonus}
