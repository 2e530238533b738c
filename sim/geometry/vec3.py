"""3-vector helpers of the numba kernels: vectors are float 3-tuples ``(x, y, z)`` (stack values, nothing allocated).

The one set used by the frames (``frames.py``), the bending/twisting element (``energies/bend_twist.py``) and the
contact geometry (``geometry_distance.py``, ``contact/obstacles.py``, ``contact/edge_pairs.py``). Each is inlined into its
caller at numba's IR level (``inline="always"``), so it is compiled with the caller's options (fastmath for the
elastic kernels, none for the contact kernels, whose results are compared bit for bit) and allocates nothing.
"""
from __future__ import annotations

import math

from numba import njit

__all__ = ["vadd", "vsub", "vmul", "vaxpy", "vdot", "vcross", "vnorm", "vlerp"]

# the options only matter for a call from Python: a kernel's call is inlined and takes the kernel's options
_OPT_INLINE = dict(inline="always", cache=True, _nrt=False)


@njit(**_OPT_INLINE)
def vadd(a, b):
    """a + b"""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(**_OPT_INLINE)
def vsub(a, b):
    """a - b"""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(**_OPT_INLINE)
def vmul(c, a):
    """c a (scalar c)"""
    return (c * a[0], c * a[1], c * a[2])


@njit(**_OPT_INLINE)
def vaxpy(s, a, b):
    """s a + b (scalar s)"""
    return (s * a[0] + b[0], s * a[1] + b[1], s * a[2] + b[2])


@njit(**_OPT_INLINE)
def vdot(a, b):
    """a · b"""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**_OPT_INLINE)
def vcross(a, b):
    """a × b"""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(**_OPT_INLINE)
def vnorm(a):
    """|a|"""
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@njit(**_OPT_INLINE)
def vlerp(a, b, s):
    """a + s (b - a)"""
    return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]))
