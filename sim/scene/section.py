"""Cross sections of a rod (docs/physics.md §1.5): area, second moments about the material directors, torsion
constant, polar moment and the radius contact uses, for ``cross_section = "circle" | "rectangle" | "ellipse"``.

Axes: ``width`` (rectangle) and the first semi-axis ``a`` (ellipse) lie along the first material director m1,
``height`` and ``b`` along m2. κ1 bends the rod in the (t, m1) plane, about m2, so it pairs with
``I1 = ∫ y1² dA`` (y1 the coordinate along m1) and κ2 with ``I2 = ∫ y2² dA``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["Section", "section_of", "rectangle_torsion_constant", "SECTIONS"]

SECTIONS = ("circle", "rectangle", "ellipse")


@dataclass(frozen=True)
class Section:
    """Section constants: area A [m²], I1/I2 [m⁴] (κ1/κ2 bending), torsion constant J [m⁴] (GJ), polar moment
    Ip = I1 + I2 [m⁴] (twist inertia ρ Ip l̄) and the contact radius [m]."""

    area: float
    I1: float
    I2: float
    J: float
    polar: float
    contact_radius: float


def rectangle_torsion_constant(w: float, h: float, terms: int = 60) -> float:
    """Saint-Venant torsion constant of a w × h rectangle by its series: with a ≥ b the long and short sides,
    J = a b³/3 · [1 − 192 b/(π⁵ a) Σ_{n odd} tanh(n π a/(2 b))/n⁵] (converged to rounding by 60 odd terms)."""
    a, b = max(w, h), min(w, h)
    s = 0.0
    for k in range(terms):
        n = 2 * k + 1
        s += math.tanh(n * math.pi * a / (2.0 * b)) / n ** 5
    return a * b ** 3 / 3.0 * (1.0 - 192.0 * b / (math.pi ** 5 * a) * s)


def section_of(rod: Any) -> Section:
    """The :class:`Section` of a :class:`sim.scene.spec.RodSpec` (its ``cross_section`` and dimensions)."""
    kind = getattr(rod, "cross_section", "circle")
    if kind == "rectangle":
        w, h = float(rod.width), float(rod.height)
        I1 = h * w ** 3 / 12.0
        I2 = w * h ** 3 / 12.0
        return Section(area=w * h, I1=I1, I2=I2, J=rectangle_torsion_constant(w, h), polar=I1 + I2,
                       contact_radius=0.5 * math.hypot(w, h))
    if kind == "ellipse":
        a, b = (float(c) for c in rod.semi_axes)
        I1 = math.pi * a ** 3 * b / 4.0
        I2 = math.pi * a * b ** 3 / 4.0
        return Section(area=math.pi * a * b, I1=I1, I2=I2, J=math.pi * a ** 3 * b ** 3 / (a * a + b * b),
                       polar=I1 + I2, contact_radius=max(a, b))
    r = float(rod.radius)
    I = math.pi * r ** 4 / 4.0  # noqa: E741
    Jp = math.pi * r ** 4 / 2.0
    return Section(area=math.pi * r * r, I1=I, I2=I, J=Jp, polar=Jp, contact_radius=r)
