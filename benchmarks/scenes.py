"""Simulator-independent definitions of the accuracy scenes (parameters, commands, references).

Every scene is described once here and realised twice: in rodlab (:mod:`benchmarks.rodlab_runs`) and
in PyElastica (:mod:`benchmarks.peers.elastica_scenes`).  SI units.

* ``static``  -- heavy cantilever: horizontal rod (+x), clamped at x = 0, sagging under its own
  weight (w L³/EI ≈ 4.9, tip drop ≈ 0.49 m), uniform viscous damping γ [1/s] on both simulators
  until static; error = |tip - tip_elastica| / L at the end.
* ``dynamic`` -- Euler-Bernoulli cantilever (docs/physics.md §8 A with E = 1e7): mode-shaped initial
  velocity, no gravity, no damping; error = max_t |z_tip - z_EB(t)| / amplitude over two periods.
* ``arm``     -- the paper arm (docs/tasks.md §1.1) under gravity with a time-varying, spatially uniform
  curvature command κ(t) = A r(t) (cos ωt, sin ωt) [1/m] (the tip circles); uniform damping
  γ on both simulators; error = max_t |tip - tip_ref(t)| / L against a converged rodlab run
  (tiny dt, many nodes, converged Newton).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .references import EulerBernoulliCantilever, heavy_elastica


@dataclass(frozen=True)
class StaticCantilever:
    length: float = 1.0
    radius: float = 0.02
    density: float = 500.0
    youngs: float = 1e7
    poisson: float = 0.5
    g: float = 9.81
    damping: float = 10.0     # γ [1/s]: ≈ critical for the first mode (ω1 ≈ 5 rad/s)
    t_end: float = 4.0        # [s] residual transient ≈ exp(-4.4 t) -> < 1e-7 m

    @property
    def EI(self) -> float:
        return self.youngs * np.pi * self.radius**4 / 4

    @property
    def area(self) -> float:
        return np.pi * self.radius**2

    def reference_tip(self, model: str = "extensible") -> np.ndarray:
        """Tip (x, z) [m] of the heavy elastica (``model`` as in :func:`heavy_elastica`)."""
        G = self.youngs / (2 * (1 + self.poisson))
        sol = heavy_elastica(length=self.length, EI=self.EI, w=self.density * self.area * self.g,
                             EA=self.youngs * self.area, GA=G * self.area, model=model)  # type: ignore
        return sol.tip


@dataclass(frozen=True)
class DynamicCantilever:
    length: float = 1.0
    radius: float = 0.02
    density: float = 500.0
    youngs: float = 1e7
    poisson: float = 0.5
    v_tip: float = 5e-3
    periods: float = 2.0

    @property
    def beam(self) -> EulerBernoulliCantilever:
        return EulerBernoulliCantilever(length=self.length, radius=self.radius, density=self.density,
                                        youngs=self.youngs, v_tip=self.v_tip)

    @property
    def t_end(self) -> float:
        return self.periods * self.beam.period


@dataclass(frozen=True)
class ArmCommand:
    """Paper arm + curvature command.  ``amp`` [1/m], ``omega`` [rad/s], ``ramp`` [s]."""

    length: float = 1.0
    radius: float = 0.05
    density: float = 1000.0
    youngs: float = 1e7
    poisson: float = 0.5
    g: float = 9.8
    damping: float = 1.273    # γ [1/s] = the paper's Elastica translational rate ν/(ρA)
    amp: float = 1.5
    omega: float = np.pi
    ramp: float = 0.5
    t_end: float = 3.0

    def kappa(self, t: float) -> np.ndarray:
        """Pointwise natural curvature (κ1, κ2) [1/m] at time ``t`` [s] (DisMech components)."""
        r = 1.0 if t >= self.ramp else (3 * (t / self.ramp) ** 2 - 2 * (t / self.ramp) ** 3)
        return self.amp * r * np.array([np.cos(self.omega * t), np.sin(self.omega * t)])

    def integrated_kappa(self, t: float, n_nodes: int) -> np.ndarray:
        """(N, 2) DisMech integrated natural curvature κ̄_i = κ(t) l_i (rows 0, N-1 zero)."""
        out = np.zeros((n_nodes, 2))
        out[1:-1] = self.kappa(t) * (self.length / (n_nodes - 1))
        return out


@dataclass(frozen=True)
class ArmPress(ArmCommand):
    """The paper arm bent toward -x (κ1 ramped to ``amp`` [1/m] over ``ramp`` s, then held) into a
    fixed horizontal cylinder (axis along y, centre (x, z) = ``cyl_xz``, radius ``cyl_radius``).
    Contact: rodlab IMC with the paper's k = 1e6, δ = 5e-3; PyElastica ``RodCylinderContact`` with the
    paper's k = 1.6e5 N/m, ν = 4 N s/m (different contact laws: part of the model gap)."""

    amp: float = 1.5
    ramp: float = 1.5
    t_end: float = 3.0
    cyl_xz: tuple[float, float] = (-0.3, 0.55)
    cyl_radius: float = 0.05
    cyl_half_length: float = 0.5

    def kappa(self, t: float) -> np.ndarray:
        s = min(1.0, max(0.0, t / self.ramp))
        return np.array([self.amp * (3 * s * s - 2 * s**3), 0.0])

    @property
    def cyl_ends(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        x, z = self.cyl_xz
        return (x, -self.cyl_half_length, z), (x, self.cyl_half_length, z)
