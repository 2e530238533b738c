"""Target motion / sampling and tip-frame quaternions, vectorised over envs (docs/tasks.md §4.2, §5.2, §5.3).

Randomness: every env owns a ``numpy.random.Generator``; all random numbers an env needs for an
episode are drawn from *its* generator at reset (per env, in a fixed order), so a batch of B envs
draws exactly what B single envs would draw and the per-step update is pure vectorised numpy.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from sim.geometry import matrix_to_quat, to_xyzw, yaw_quat

__all__ = ["FollowTargetMotion", "sample_ik_targets", "matrix_to_quat_xyzw", "yaw_quat_xyzw"]

TWO_PI = 2.0 * math.pi


class FollowTargetMotion:
    """Constant-speed target with random direction changes, reflected at the box faces (docs/tasks.md §4.2).

    pos (B, D) [m], vel (B, D) [m/s], D = 3 (x, y, z) or 2 (x, z).
    Per control step (after the rod sub-steps): (1) negate the velocity component of every axis whose
    position is strictly outside [lo, hi]; (2) only if no axis was outside, with probability
    ``p_change`` draw a new direction; (3) pos += vel * dt.
    Direction (alpha, beta ~ U[0, 2 pi)): 3D v = v0 (cos a sin b, sin a sin b, cos b); 2D
    v = v0 (cos a sin b, cos b) - not normalised, as in the reference (O3).
    At reset every env draws, from its own generator and in this order: the position (D uniforms),
    the initial direction (2 uniforms), then a table (3, horizon) of per-step uniforms
    (change test, alpha, beta) consumed one column per control step (wrapping after ``horizon``).
    """

    def __init__(self, envs: int, *, dim: int, lo: Sequence[float], hi: Sequence[float], speed: float,
                 p_change: float, dt: float, horizon: int):
        if dim not in (2, 3) or len(lo) != dim or len(hi) != dim:
            raise ValueError(f"FollowTargetMotion: dim must be 2 or 3 with matching box, got {dim}, {lo}, {hi}")
        self.envs, self.dim = int(envs), int(dim)
        self.lo = np.asarray(lo, np.float64)
        self.hi = np.asarray(hi, np.float64)
        self.speed, self.p_change, self.dt = float(speed), float(p_change), float(dt)
        self.horizon = int(horizon)
        self.pos = np.zeros((self.envs, dim))
        self.vel = np.zeros((self.envs, dim))
        self.t = np.zeros(self.envs, dtype=np.int64)
        self.table = np.zeros((self.envs, 3, self.horizon))

    def _direction(self, ua: np.ndarray, ub: np.ndarray) -> np.ndarray:
        a, b = TWO_PI * ua, TWO_PI * ub
        if self.dim == 3:
            v = np.stack([np.cos(a) * np.sin(b), np.sin(a) * np.sin(b), np.cos(b)], axis=-1)
        else:
            v = np.stack([np.cos(a) * np.sin(b), np.cos(b)], axis=-1)
        return self.speed * v

    def reset(self, idx: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        """Re-sample the envs in ``idx`` (int indices) from ``rngs[i]``."""
        for i in np.asarray(idx, dtype=np.int64):
            rng = rngs[i]
            self.pos[i] = self.lo + (self.hi - self.lo) * rng.random(self.dim)
            ua, ub = rng.random(2)
            self.vel[i] = self._direction(np.float64(ua), np.float64(ub))
            self.table[i] = rng.random((3, self.horizon))
            self.t[i] = 0

    def advance(self) -> None:
        """One control step of target motion for all envs."""
        outside = (self.pos < self.lo) | (self.pos > self.hi)
        self.vel = np.where(outside, -self.vel, self.vel)
        col = self.t % self.horizon
        rows = np.arange(self.envs)
        u = self.table[rows, :, col]                      # (B, 3)
        change = (~outside.any(axis=1)) & (u[:, 0] < self.p_change)
        if change.any():
            self.vel[change] = self._direction(u[change, 1], u[change, 2])
        self.pos = self.pos + self.vel * self.dt
        self.t += 1


def yaw_quat_xyzw(yaw: np.ndarray) -> np.ndarray:
    """(B,) yaw [rad] about world z -> (B, 4) scalar-last quaternion (0, 0, sin(y/2), cos(y/2))."""
    return to_xyzw(yaw_quat(yaw))


def sample_ik_targets(rng: np.random.Generator, *, lo: Sequence[float], hi: Sequence[float],
                      yaw_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """One IK target from ``rng``: position uniform in the box (3 uniforms, then) yaw uniform (1 uniform).

    Returns (pos (3,) [m], quat (4,) xyzw: the observation's ``target_quat`` layout, docs/conventions.md).
    """
    lo_a, hi_a = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    pos = lo_a + (hi_a - lo_a) * rng.random(3)
    yaw = yaw_range[0] + (yaw_range[1] - yaw_range[0]) * rng.random()
    return pos, yaw_quat_xyzw(np.float64(yaw))


def matrix_to_quat_xyzw(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> scalar-last quaternions (..., 4), SciPy's convention
    (:func:`sim.geometry.rotations.matrix_to_quat`, reordered)."""
    return to_xyzw(matrix_to_quat(R))
