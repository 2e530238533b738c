"""Hand-written reference controllers (no learning), vectorised over envs.

:func:`arc_controller` steers the accumulated curvature K toward the constant-curvature arc whose
chord points at the target: total bend angle Phi = 2 atan2(horizontal distance, height) in the
vertical plane through the target, spread evenly over the control points (positive kappa1 bends the
upright arm toward -x, kappa2 toward -y). Used by the tests (task solvable in principle) and as a
sanity baseline in the workbench. Only meaningful for the intended smoothing (weights sum to 1).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["arc_controller"]


def arc_controller(core, *, gain: float = 1.0, twist: bool = True) -> np.ndarray:
    """Actions (B, action_dim) in [-1, 1] for a Follow / IK / obstacle core, from its current target."""
    cfg = core.converter.cfg
    P = cfg.n_points
    if hasattr(core, "target") and hasattr(core.target, "pos"):
        tgt = np.asarray(core.target.pos, np.float64)
    elif hasattr(core, "target_pos"):
        tgt = np.asarray(core.target_pos, np.float64)
    else:
        tgt = np.asarray(core.target, np.float64)
    B = core.envs
    if cfg.planar:
        x, z = tgt[:, 0], tgt[:, 1]
        phi_tot = 2.0 * np.arctan2(np.abs(x), z)
        K_des = (-np.sign(x) * phi_tot / P)[:, None, None] * np.ones((B, P, 1))
    else:
        x, y, z = tgt[:, 0], tgt[:, 1], tgt[:, 2]
        h = np.hypot(x, y)
        phi_tot = 2.0 * np.arctan2(h, z)
        ang = np.arctan2(y, x)
        k = phi_tot / P
        K_des = np.stack([-k * np.cos(ang), -k * np.sin(ang)], axis=-1)[:, None, :] * np.ones((B, P, 2))
    K_des = np.clip(K_des, -cfg.kappa_limit, cfg.kappa_limit)
    a_bend = gain * (K_des - core.converter.K.astype(np.float64)) / cfg.kappa_scale
    parts = [a_bend.reshape(B, -1)]
    if cfg.has_twist:
        a_tw = np.zeros((B, P))
        if twist and hasattr(core, "target_quat"):
            q = core.target_quat
            yaw = 2.0 * np.arctan2(q[:, 2], q[:, 3])
            # tip yaw starts at pi; natural twist rotates the frame about the tangent
            d = np.mod(yaw - math.pi + math.pi, 2 * math.pi) - math.pi
            T_des = np.clip(d / P, -cfg.twist_limit, cfg.twist_limit)[:, None] * np.ones((B, P))
            a_tw = gain * (T_des - core.converter.T.astype(np.float64)) / cfg.twist_scale
        parts.append(a_tw)
    return np.clip(np.concatenate(parts, axis=1), -1.0, 1.0).astype(np.float32)
