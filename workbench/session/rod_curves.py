"""Curvature along the rod: commanded (natural) against actual, per component, for the Plots tab.

Integrated values per node (docs/physics.md §1.4, dimensionless / rad): the material curvatures κ1, κ2
(``sim.geometry.curvature.material_curvature``) and the twist between neighbouring edges (the angle of m1 about the tangent
after parallel transport, as the rod colouring computes it), against the natural values the controller holds
(``ctrl.kappa_bar``, ``ctrl.tau_bar``). A 2-D rod has one in-plane component: the material component
``planar_component`` (the one ``kappa_bar`` holds for 2-D rods, docs/physics.md §1.6). End nodes are 0.

Live sessions read the simulator; replays read what the episode recorded (``kappa_bar``/``kappa``/``tau_bar``/``tau``)
and compute the actual values from the recorded positions and material frames when they were not logged.
"""
from __future__ import annotations

import numpy as np

from sim.geometry import integrated_twist, material_curvature

#: component name -> (index into κ (N, 2), or "twist")
COMPONENTS_3D = ("κ1", "κ2", "twist")
PLANAR = "κ (in-plane)"


def planar_component(m1: np.ndarray, m2: np.ndarray) -> int:
    """Which material component lies in the x-z plane of a 2-D rod, from its first edge's directors (the rule of
    ``sim.scene.model``: κ1 when m2 is along ±y, else κ2)."""
    return 0 if abs(float(np.asarray(m2)[0][1])) > 0.5 else 1


def curves(x, m1, m2, *, kappa_bar=None, tau_bar=None, planar: int | None = None,
           actual_kappa=None, actual_tau=None) -> dict[str, tuple[np.ndarray | None, np.ndarray | None]]:
    """component -> (commanded (N,) or None, actual (N,) or None).

    Args:
        x: (N, 3) node positions [m]; m1, m2: (N-1, 3) material directors (None: actual values unknown unless given).
        kappa_bar: (N, 2) or (N, 1) natural curvature; tau_bar: (N,) natural twist (3-D only).
        planar: the in-plane material component of a 2-D rod (0 or 1), None for a 3-D rod.
        actual_kappa / actual_tau: recorded actual values (used instead of computing them).
    """
    x = np.asarray(x, np.float64)
    n = len(x)
    kap = None
    if actual_kappa is not None:
        kap = np.asarray(actual_kappa, np.float64).reshape(n, -1)
    elif m1 is not None and m2 is not None:
        kap = material_curvature(x, np.asarray(m1, np.float64), np.asarray(m2, np.float64))
    kb = None if kappa_bar is None else np.asarray(kappa_bar, np.float64).reshape(n, -1)
    out: dict[str, tuple[np.ndarray | None, np.ndarray | None]] = {}
    if planar is not None:
        act = None if kap is None else kap[:, 0 if kap.shape[1] == 1 else planar]
        out[PLANAR] = (None if kb is None else kb[:, 0], act)
        return out
    for j, name in enumerate(COMPONENTS_3D[:2]):
        out[name] = (None if kb is None or kb.shape[1] <= j else kb[:, j],
                     None if kap is None or kap.shape[1] <= j else kap[:, j])
    tw = None
    if actual_tau is not None:
        tw = np.asarray(actual_tau, np.float64).reshape(n)
    elif m1 is not None:
        tw = integrated_twist(x, np.asarray(m1, np.float64))
        tw[0] = tw[-1] = 0.0
    out["twist"] = (None if tau_bar is None else np.asarray(tau_bar, np.float64).reshape(n), tw)
    return out


def live_curves(wb) -> dict[str, tuple[np.ndarray | None, np.ndarray | None]]:
    """The live rod's curves (commanded and actual curvature and twist)."""
    with wb.lock:
        live = wb.live
        x = np.asarray(live.state.node_pos[0], np.float64).copy()
        mf = live.sim.material_frames(live.state)
        m1, m2 = np.asarray(mf[0][0], np.float64), np.asarray(mf[1][0], np.float64)
        kb = np.asarray(live.ctrl.kappa_bar[0], np.float64).copy()
        tb = np.asarray(live.ctrl.tau_bar[0], np.float64).copy()
        planar = int(live.model.planar_component) if getattr(live.model, "mode", "3d") == "2d" else None
    return curves(x, m1, m2, kappa_bar=kb, tau_bar=None if planar is not None else tb, planar=planar)


def replay_curves(ep, i: int) -> dict[str, tuple[np.ndarray | None, np.ndarray | None]]:
    """Frame ``i`` of a recorded episode (``policies.recording.EpisodeData``)."""
    def at(a):
        if a is None:
            return None
        v = np.asarray(a[i], np.float64)
        return v if np.all(np.isfinite(v)) else None

    x = np.asarray(ep.positions[i], np.float64)
    m1, m2 = at(ep.m1), at(ep.m2)
    planar = None
    if getattr(ep.scene, "planar", False):
        planar = planar_component(ep.m1[0], ep.m2[0]) if ep.m1 is not None and ep.m2 is not None else 0
    return curves(x, m1, m2, kappa_bar=at(ep.kappa_bar), tau_bar=at(ep.tau_bar), planar=planar,
                  actual_kappa=at(ep.kappa), actual_tau=at(ep.tau))
