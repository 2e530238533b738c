"""Bending and twisting of one interior node of a 3-D rod (docs/physics.md §2.2, §2.3).

E_b = 1/(2 l_i) [EI1 (κ1 − κ̄1)² + EI2 (κ2 − κ̄2)²],  E_t = GJ/(2 l_i) (τ − τ̄)², τ = θ_f − θ_e + β.
Full-Newton symmetric Hessians (∇κ∇κᵀ + (κ − κ̄)∇²κ), exact at the frame-transport base (§2.4).
Local 11-DOF order: [x_{i−1}(3), θ_e, x_i(3), θ_f, x_{i+1}(3)] = global DOFs 4(i−1) … 4(i−1)+10.
Curvatures and twist are integrated (dimensionless / rad); EI [N·m²], GJ [N·m²], l_i [m].
"""
from __future__ import annotations

import math

from numba import njit

from sim.geometry.vec3 import vadd, vaxpy, vcross, vdot, vmul, vnorm, vsub
from sim.numba_options import OPT

__all__ = ["bend_twist_core", "bend_twist_element", "material_curvatures", "material_directors"]



@njit(inline="always", **OPT)
def _skew_row(V, r, a, b):
    """([v]×)_{ab} for v = V[r], with [v]× w = v × w."""
    if a == b:
        return 0.0
    if a == 0:
        return -V[r, 2] if b == 1 else V[r, 1]
    if a == 1:
        return V[r, 2] if b == 0 else -V[r, 0]
    return -V[r, 1] if b == 0 else V[r, 0]


@njit(**OPT)
def material_curvatures(xm, xi, xp, m1e, m2e, m1f, m2f):
    """(κ1, κ2) of node i from positions and material directors (3-tuples)."""
    e = vsub(xi, xm)
    f = vsub(xp, xi)
    te = vmul(1.0 / vnorm(e), e)
    tf = vmul(1.0 / vnorm(f), f)
    kb = vmul(2.0 / (1.0 + vdot(te, tf)), vcross(te, tf))
    return 0.5 * vdot(kb, vadd(m2e, m2f)), -0.5 * vdot(kb, vadd(m1e, m1f))


@njit(**OPT)
def bend_twist_element(xm, xi, xp, d1e, d2e, d1f, d2f, the, thf, beta, kbar1, kbar2, taubar,
                       EI1, EI2, GJ, lv, g, H, wk, with_hess):
    """Energy, gradient and Hessian of bending + twisting at one interior node.

    xm, xi, xp: node positions x_{i−1}, x_i, x_{i+1} (3-tuples, m); d1e, d2e, d1f, d2f: reference directors
    of edges i−1 (e) and i (f); the, thf: twist angles [rad]; beta: reference twist [rad].
    Writes g (11,), and the full symmetric H (11, 11) if with_hess; wk is (17, 11) scratch.
    Returns (E_bend, E_twist) [J]. The solver calls :func:`bend_twist_core` with the material directors of
    each edge computed once.
    """
    m1e, m2e = material_directors(d1e, d2e, the)
    m1f, m2f = material_directors(d1f, d2f, thf)
    return bend_twist_core(xm, xi, xp, m1e, m2e, m1f, m2f, thf - the + beta, kbar1, kbar2, taubar, EI1, EI2, GJ,
                           lv, g, H, wk, with_hess, False)


@njit(inline="always", **OPT)
def material_directors(d1, d2, theta):
    """(m1, m2) = (cos θ d1 + sin θ d2, −sin θ d1 + cos θ d2) of one edge (3-tuples)."""
    c = math.cos(theta)
    s = math.sin(theta)
    return vaxpy(c, d1, vmul(s, d2)), vaxpy(-s, d1, vmul(c, d2))


@njit(**OPT)
def bend_twist_core(xm, xi, xp, m1e, m2e, m1f, m2f, tau, kbar1, kbar2, taubar, EI1, EI2, GJ, lv, g, H, wk,
                    with_hess, upper_only):
    """:func:`bend_twist_element` from the material directors m1, m2 of edges e and f and the twist
    τ = θ_f − θ_e + β. With ``upper_only`` only H's upper triangle (q ≥ p) is written (what the symmetric
    banded assembly reads); the lower triangle is then left unspecified."""
    e = vsub(xi, xm)
    f = vsub(xp, xi)
    ne = vnorm(e)
    nf = vnorm(f)
    te = vmul(1.0 / ne, e)
    tf = vmul(1.0 / nf, f)
    chi = 1.0 + vdot(te, tf)
    ichi = 1.0 / chi
    kb = vmul(2.0 * ichi, vcross(te, tf))
    k1 = 0.5 * vdot(kb, vadd(m2e, m2f))
    k2 = -0.5 * vdot(kb, vadd(m1e, m1f))
    tt = vmul(ichi, vadd(te, tf))
    mt1 = vmul(ichi, vadd(m1e, m1f))
    mt2 = vmul(ichi, vadd(m2e, m2f))
    a1v = vcross(tf, mt2)   # a
    b1v = vcross(te, mt2)   # b
    c2v = vcross(tf, mt1)   # c
    d2v = vcross(te, mt1)   # d
    ine = 1.0 / ne
    inf = 1.0 / nf
    Dk1e = vmul(ine, vaxpy(-k1, tt, a1v))
    Dk1f = vmul(inf, vaxpy(-k1, tt, vmul(-1.0, b1v)))
    Dk2e = vmul(ine, vaxpy(-k2, tt, vmul(-1.0, c2v)))
    Dk2f = vmul(inf, vaxpy(-k2, tt, d2v))
    Dte = vmul(0.5 * ine, kb)
    Dtf = vmul(0.5 * inf, kb)
    kbm1e = vdot(kb, m1e)
    kbm1f = vdot(kb, m1f)
    kbm2e = vdot(kb, m2e)
    kbm2f = vdot(kb, m2f)
    gk1 = wk[0]
    gk2 = wk[1]
    gt = wk[2]
    for a in range(3):
        gk1[a] = -Dk1e[a]
        gk1[4 + a] = Dk1e[a] - Dk1f[a]
        gk1[8 + a] = Dk1f[a]
        gk2[a] = -Dk2e[a]
        gk2[4 + a] = Dk2e[a] - Dk2f[a]
        gk2[8 + a] = Dk2f[a]
        gt[a] = -Dte[a]
        gt[4 + a] = Dte[a] - Dtf[a]
        gt[8 + a] = Dtf[a]
    gk1[3] = -0.5 * kbm1e
    gk1[7] = -0.5 * kbm1f
    gk2[3] = -0.5 * kbm2e
    gk2[7] = -0.5 * kbm2f
    gt[3] = -1.0
    gt[7] = 1.0
    s1 = EI1 / lv
    s2 = EI2 / lv
    s3 = GJ / lv
    dk1 = k1 - kbar1
    dk2 = k2 - kbar2
    dtw = tau - taubar
    c1 = s1 * dk1
    c2 = s2 * dk2
    c3 = s3 * dtw
    for p in range(11):
        g[p] = c1 * gk1[p] + c2 * gk2[p] + c3 * gt[p]
    if with_hess:
        ie2 = ine * ine
        if2 = inf * inf
        ief = ine * inf
        # copy the 3-vectors into rows of the scratch wk (indexing a tuple with a loop variable compiles to a
        # switch in numba, which made this section ~5x slower)
        V = wk[3:]
        for a in range(3):
            V[0, a] = tt[a]
            V[1, a] = te[a]
            V[2, a] = tf[a]
            V[3, a] = kb[a]
            V[4, a] = m1e[a]
            V[5, a] = m2e[a]
            V[6, a] = m1f[a]
            V[7, a] = m2f[a]
            V[8, a] = a1v[a]
            V[9, a] = b1v[a]
            V[10, a] = c2v[a]
            V[11, a] = d2v[a]
            V[12, a] = mt1[a]
            V[13, a] = mt2[a]
        # Aee and Aff (the x_{i−1}/x_{i+1} curvature blocks) are symmetric in (a, b): b >= a, mirrored
        for a in range(3):
            for b in range(a, 3):
                tta, ttb = V[0, a], V[0, b]
                tea, teb = V[1, a], V[1, b]
                tfa, tfb = V[2, a], V[2, b]
                kba, kbb = V[3, a], V[3, b]
                ttab = tta * ttb
                dab = 1.0 if a == b else 0.0
                pe = dab - tea * teb
                pf = dab - tfa * tfb
                k1ee = ((2.0 * k1 * ttab - (V[8, a] * ttb + tta * V[8, b])) - k1 * pe * ichi
                        + 0.25 * (kba * V[5, b] + V[5, a] * kbb)) * ie2
                k1ff = ((2.0 * k1 * ttab + (V[9, a] * ttb + tta * V[9, b])) - k1 * pf * ichi
                        + 0.25 * (kba * V[7, b] + V[7, a] * kbb)) * if2
                k2ee = ((2.0 * k2 * ttab + (V[10, a] * ttb + tta * V[10, b])) - k2 * pe * ichi
                        - 0.25 * (kba * V[4, b] + V[4, a] * kbb)) * ie2
                k2ff = ((2.0 * k2 * ttab - (V[11, a] * ttb + tta * V[11, b])) - k2 * pf * ichi
                        - 0.25 * (kba * V[6, b] + V[6, a] * kbb)) * if2
                tee = -0.25 * (kba * (teb + ttb) + (tea + tta) * kbb) * ie2
                tff = -0.25 * (kba * (tfb + ttb) + (tfa + tta) * kbb) * if2
                Aee = c1 * k1ee + c2 * k2ee + c3 * tee
                Aff = c1 * k1ff + c2 * k2ff + c3 * tff
                H[a, b] = Aee
                H[b, a] = Aee
                H[8 + a, 8 + b] = Aff
                H[8 + b, 8 + a] = Aff
        # Aef (x_{i−1}/x_{i+1} mixed block) is not symmetric: all nine
        for a in range(3):
            for b in range(3):
                tta, ttb = V[0, a], V[0, b]
                tea, tfb = V[1, a], V[2, b]
                kba = V[3, a]
                ttab = tta * ttb
                dab = 1.0 if a == b else 0.0
                k1ef = (-k1 * (dab + tea * tfb) * ichi
                        + 2.0 * k1 * ttab - V[8, a] * ttb + tta * V[9, b] - _skew_row(V, 13, a, b)) * ief
                k2ef = (-k2 * (dab + tea * tfb) * ichi
                        + 2.0 * k2 * ttab + V[10, a] * ttb - tta * V[11, b] + _skew_row(V, 12, a, b)) * ief
                tef = 0.5 * (2.0 * ichi * _skew_row(V, 1, a, b) - kba * ttb) * ief
                Aef = c1 * k1ef + c2 * k2ef + c3 * tef
                Aee = H[a, b]
                Aff = H[8 + a, 8 + b]
                H[a, 4 + b] = -Aee + Aef
                H[a, 8 + b] = -Aef
                H[4 + a, 8 + b] = Aef
                H[4 + a, 4 + b] = Aee + Aff
        # H[i,i] needs −Aef − Afe, H[i,i+1] needs −Aff: second pass using the (a, b) blocks above
        for a in range(3):
            for b in range(3):
                aef_ab = H[4 + a, 8 + b]
                aef_ba = H[4 + b, 8 + a]
                H[4 + a, 4 + b] = H[4 + a, 4 + b] - aef_ab - aef_ba
        for a in range(3):
            for b in range(3):
                H[4 + a, 8 + b] = H[4 + a, 8 + b] - H[8 + a, 8 + b]
        # edge–θ columns
        for gi in range(2):
            col = 3 if gi == 0 else 7
            kbm1g = kbm1e if gi == 0 else kbm1f
            kbm2g = kbm2e if gi == 0 else kbm2f
            r1 = 4 if gi == 0 else 6   # row of m1g in V
            r2 = r1 + 1                # row of m2g
            for a in range(3):
                a1 = (a + 1) % 3
                a2 = (a + 2) % 3
                # (u × w)_a = u_{a1} w_{a2} − u_{a2} w_{a1}
                tfm1 = V[2, a1] * V[r1, a2] - V[2, a2] * V[r1, a1]
                tem1 = V[1, a1] * V[r1, a2] - V[1, a2] * V[r1, a1]
                tfm2 = V[2, a1] * V[r2, a2] - V[2, a2] * V[r2, a1]
                tem2 = V[1, a1] * V[r2, a2] - V[1, a2] * V[r2, a1]
                tta = V[0, a]
                ve = (c1 * (0.5 * kbm1g * tta - tfm1 * ichi) + c2 * (0.5 * kbm2g * tta - tfm2 * ichi)) * ine
                vf = (c1 * (0.5 * kbm1g * tta + tem1 * ichi) + c2 * (0.5 * kbm2g * tta + tem2 * ichi)) * inf
                H[a, col] = -ve
                H[col, a] = -ve
                H[4 + a, col] = ve - vf
                H[col, 4 + a] = ve - vf
                H[8 + a, col] = vf
                H[col, 8 + a] = vf
        H[3, 3] = c1 * (-0.5 * kbm2e) + c2 * (0.5 * kbm1e)
        H[7, 7] = c1 * (-0.5 * kbm2f) + c2 * (0.5 * kbm1f)
        H[3, 7] = 0.0
        H[7, 3] = 0.0
        # every upper entry is set now (the off-diagonal node blocks (0,4), (0,8), (4,8) are upper); add the
        # Gauss–Newton part on the upper triangle, then mirror unless the caller reads the upper half only
        for p in range(11):
            u1 = s1 * gk1[p]
            u2 = s2 * gk2[p]
            u3 = s3 * gt[p]
            for q in range(p, 11):
                H[p, q] += u1 * gk1[q] + u2 * gk2[q] + u3 * gt[q]
        if not upper_only:
            for p in range(11):
                for q in range(p + 1, 11):
                    H[q, p] = H[p, q]
    return 0.5 * (s1 * dk1 * dk1 + s2 * dk2 * dk2), 0.5 * s3 * dtw * dtw
