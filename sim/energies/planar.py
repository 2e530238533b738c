"""Planar (2-D) bending of one interior node (docs/physics.md §1.6 [REC]), exact gradient and Hessian.

κ = 2 tan(φ/2), φ = atan2(e_x f_z − e_z f_x, e·f) the counter-clockwise turning angle (x right, z up),
e = x_i − x_{i−1}, f = x_{i+1} − x_i. E_b = EI/(2 l_i) (κ − κ̄)². Local DOF order:
[x_{i−1}, z_{i−1}, x_i, z_i, x_{i+1}, z_{i+1}]. κ is the integrated (dimensionless) curvature.
"""
from __future__ import annotations

from numba import njit

__all__ = ["planar_bend_element"]


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"})
def planar_bend_element(xm, xi, xp, kbar, EI, lv, g, H, with_hess):
    """Writes g (6,) and, if with_hess, H (6, 6); returns (energy [J], κ)."""
    ex = xi[0] - xm[0]
    ez = xi[1] - xm[1]
    fx = xp[0] - xi[0]
    fz = xp[1] - xi[1]
    ne2 = ex * ex + ez * ez
    nf2 = fx * fx + fz * fz
    ne = ne2 ** 0.5
    nf = nf2 ** 0.5
    c = ex * fz - ez * fx
    d = ex * fx + ez * fz
    kap = 2.0 * c / (ne * nf + d)
    kp = 1.0 + 0.25 * kap * kap          # dκ/dφ
    kpp = 0.5 * kap * kp                 # d²κ/dφ²
    # ∇φ w.r.t. e and f
    pe0 = ez / ne2
    pe1 = -ex / ne2
    pf0 = -fz / nf2
    pf1 = fx / nf2
    a = EI / lv
    dk = kap - kbar
    # node gradient of φ
    gphi = (-pe0, -pe1, pe0 - pf0, pe1 - pf1, pf0, pf1)
    s = a * dk * kp
    for k in range(6):
        g[k] = s * gphi[k]
    if with_hess:
        # Hessian of φ: ee = sym(perp(e), e)/|e|^4, ff = -sym(perp(f), f)/|f|^4, perp(v) = (-v_z, v_x)
        ie4 = 1.0 / (ne2 * ne2)
        if4 = 1.0 / (nf2 * nf2)
        # sym(p, v) with p = (-vz, vx): [[-2 vx vz, vx² - vz²], [vx² - vz², 2 vx vz]]
        Aee00 = -2.0 * ex * ez * ie4
        Aee01 = (ex * ex - ez * ez) * ie4
        Aee11 = 2.0 * ex * ez * ie4
        Aff00 = 2.0 * fx * fz * if4
        Aff01 = -(fx * fx - fz * fz) * if4
        Aff11 = -2.0 * fx * fz * if4
        c2 = a * dk * kp          # coefficient of ∇²φ
        c1 = a * (kp * kp + dk * kpp)   # coefficient of ∇φ∇φᵀ
        for p in range(6):
            for q in range(6):
                H[p, q] = c1 * gphi[p] * gphi[q]
        Aee = ((Aee00, Aee01), (Aee01, Aee11))
        Aff = ((Aff00, Aff01), (Aff01, Aff11))
        for p in range(2):
            for q in range(2):
                ee = c2 * Aee[p][q]
                ff = c2 * Aff[p][q]
                H[p, q] += ee
                H[p, 2 + q] -= ee
                H[2 + p, q] -= ee
                H[2 + p, 2 + q] += ee + ff
                H[2 + p, 4 + q] -= ff
                H[4 + p, 2 + q] -= ff
                H[4 + p, 4 + q] += ff
    return 0.5 * a * dk * dk, kap
