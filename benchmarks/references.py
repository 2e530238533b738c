"""Closed-form / quasi-closed-form reference solutions for the accuracy benchmarks.

Two references (SI units throughout):

* :func:`heavy_elastica` -- static large deflection of a horizontal cantilever under its own weight
  (uniform load ``w`` [N/m] per reference length) and an optional tip load ``P`` [N], solved as a
  two-point boundary value problem with :func:`scipy.integrate.solve_bvp`.  Three rod models:

  - ``"inextensible"``: the classical Kirchhoff elastica, ``EI θ'' = -W(s) cos θ``;
  - ``"extensible"``: axial strain ``ε = T/EA`` (what DER models: stretch, no shear);
  - ``"shearable"``: extensible plus Reissner shear ``γ = V/(α_s G A)`` (what a Cosserat rod
    such as PyElastica models; ``α_s`` = 4/3 is PyElastica's shear coefficient).

  ``θ(s)`` is the angle of the tangent (director) below the horizontal, ``W(s) = w (L - s) + P`` the
  load carried beyond ``s``, ``EI θ'' = -W(s) x'(s)``, ``θ(0) = 0``, ``θ'(L) = 0``.

* :class:`EulerBernoulliCantilever` -- first clamped-free bending mode of a linear Euler-Bernoulli
  beam: ``ω1 = (β1 L)² sqrt(EI / (ρ A L⁴))``, mode shape ``φ(x)`` and the tip response
  ``z(t) = (v_tip / ω1) sin(ω1 t)`` to the initial velocity ``v(x) = v_tip φ(x)/φ(L)``
  (docs/physics.md §8 A).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.integrate import cumulative_trapezoid, solve_bvp

RodModel = Literal["inextensible", "extensible", "shearable"]

BETA1_L = 1.8751040687119611  # first root of 1 + cos(x) cosh(x) = 0
SIGMA1 = (np.sinh(BETA1_L) - np.sin(BETA1_L)) / (np.cosh(BETA1_L) + np.cos(BETA1_L))


@dataclass(frozen=True)
class ElasticaSolution:
    """Deformed centreline of the heavy elastica.

    Attributes: ``s`` (M,) reference arc length [m]; ``x``, ``z`` (M,) position [m] (clamp at the
    origin, beam along +x, gravity along -z); ``theta`` (M,) tangent angle below horizontal [rad].
    """

    s: np.ndarray
    x: np.ndarray
    z: np.ndarray
    theta: np.ndarray

    @property
    def tip(self) -> np.ndarray:
        """Tip position ``(x, z)`` [m]."""
        return np.array([self.x[-1], self.z[-1]])


def heavy_elastica(*, length: float, EI: float, w: float, P: float = 0.0, EA: float = np.inf,
                   GA: float = np.inf, shear_coeff: float = 4.0 / 3.0,
                   model: RodModel = "extensible", n_mesh: int = 401,
                   tol: float = 1e-10) -> ElasticaSolution:
    """Static cantilever under distributed load ``w`` [N/m] and tip load ``P`` [N] (both along -z).

    ``EI`` [N m²], ``EA`` [N] (ignored for ``model="inextensible"``), ``GA`` = G·A [N] (used only for
    ``"shearable"``; the shear stiffness is ``shear_coeff * GA``).  Returns the centreline sampled at
    ``n_mesh`` points.  Raises ``ValueError`` on non-positive stiffness or if the BVP fails.
    """
    if not (length > 0 and EI > 0 and EA > 0 and GA > 0):
        raise ValueError("heavy_elastica: length, EI, EA, GA must be positive")
    if model not in ("inextensible", "extensible", "shearable"):
        raise ValueError(f"heavy_elastica: unknown model {model!r}")
    inv_ea = 0.0 if model == "inextensible" else 1.0 / EA
    inv_ga = 1.0 / (shear_coeff * GA) if model == "shearable" else 0.0
    L = float(length)

    def strains(s, th):
        W = w * (L - s) + P
        eps = W * np.sin(th) * inv_ea          # tension / EA
        gam = -W * np.cos(th) * inv_ga         # shear force / (α G A)
        return W, eps, gam

    def rhs(s, y):
        th, k = y
        W, eps, gam = strains(s, th)
        dx = (1.0 + eps) * np.cos(th) + gam * np.sin(th)
        return np.vstack([k, -W * dx / EI])

    def bc(ya, yb):
        return np.array([ya[0], yb[1]])

    s = np.linspace(0.0, L, n_mesh)
    th_lin = (w / (6 * EI)) * (L**3 - (L - s) ** 3) + (P / (2 * EI)) * (L**2 - (L - s) ** 2)
    th_lin = np.clip(th_lin, 0.0, 1.4)
    k_lin = np.gradient(th_lin, s)
    sol = solve_bvp(rhs, bc, s, np.vstack([th_lin, k_lin]), tol=tol, max_nodes=200000)
    if not sol.success:
        raise ValueError(f"heavy_elastica: BVP did not converge ({sol.message})")
    th = sol.sol(s)[0]
    # integrate the centreline on an 8x finer grid (trapezoid error O(h²) -> negligible)
    fine = np.linspace(0.0, L, 8 * n_mesh - 7)
    thf = sol.sol(fine)[0]
    _, epsf, gamf = strains(fine, thf)
    xf = cumulative_trapezoid((1 + epsf) * np.cos(thf) + gamf * np.sin(thf), fine, initial=0.0)
    zf = cumulative_trapezoid(-(1 + epsf) * np.sin(thf) + gamf * np.cos(thf), fine, initial=0.0)
    x, z = xf[::8], zf[::8]
    return ElasticaSolution(s=s, x=x, z=z, theta=th)


@dataclass(frozen=True)
class EulerBernoulliCantilever:
    """Linear clamped-free beam of length ``length`` [m], radius ``radius`` [m], density
    ``density`` [kg/m³], Young's modulus ``youngs`` [Pa], circular section."""

    length: float = 1.0
    radius: float = 0.02
    density: float = 500.0
    youngs: float = 1e7
    v_tip: float = 5e-3

    @property
    def EI(self) -> float:
        return self.youngs * np.pi * self.radius**4 / 4.0

    @property
    def rhoA(self) -> float:
        return self.density * np.pi * self.radius**2

    @property
    def omega1(self) -> float:
        """First natural angular frequency [rad/s]."""
        return BETA1_L**2 * np.sqrt(self.EI / (self.rhoA * self.length**4))

    @property
    def period(self) -> float:
        return 2 * np.pi / self.omega1

    @property
    def amplitude(self) -> float:
        """Tip amplitude [m] of the response to the mode-shaped initial velocity."""
        return self.v_tip / self.omega1

    def mode_shape(self, x: np.ndarray) -> np.ndarray:
        """First mode ``φ(x)`` (unnormalised; ``φ(L) ≈ 2``), ``x`` [m] any shape."""
        b = BETA1_L / self.length
        bx = b * np.asarray(x, dtype=float)
        return np.cosh(bx) - np.cos(bx) - SIGMA1 * (np.sinh(bx) - np.sin(bx))

    def initial_velocity(self, x: np.ndarray) -> np.ndarray:
        """Transverse initial velocity [m/s] at positions ``x`` [m]: ``v_tip φ(x)/φ(L)``."""
        return self.v_tip * self.mode_shape(x) / self.mode_shape(np.array(self.length))

    def tip_z(self, t: np.ndarray) -> np.ndarray:
        """Tip deflection [m] at times ``t`` [s]."""
        return self.amplitude * np.sin(self.omega1 * np.asarray(t, dtype=float))


def trajectory_error(t: np.ndarray, y: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray, *,
                     scale: float = 1.0) -> float:
    """Max-norm distance between two sampled trajectories, divided by ``scale``.

    ``t`` (K,) [s], ``y`` (K, D) or (K,); the reference ``(t_ref, y_ref)`` is linearly
    interpolated to the times ``t`` that lie inside its range.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float).reshape(len(t), -1)
    yr = np.asarray(y_ref, float).reshape(len(t_ref), -1)
    m = (t >= t_ref[0] - 1e-12) & (t <= t_ref[-1] + 1e-12)
    if not m.any():
        raise ValueError("trajectory_error: no overlap between the time ranges")
    yi = np.stack([np.interp(t[m], t_ref, yr[:, d]) for d in range(yr.shape[1])], axis=1)
    return float(np.max(np.linalg.norm(y[m] - yi, axis=1)) / scale)
